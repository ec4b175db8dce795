defmodule Neptunus.FirmwareRecord do
  @moduledoc """
  The record of the last firmware update of a Neptunus SD-card image (`rel/firmware/`):
  written by the card's `neptunus-firmware` when an update is kept (`result=updated`) or when
  the boot loader went back to the previous firmware (`result=rolled-back`, with the
  `reason`). `GET /api/health` carries it as `firmware_update` and the operator page says
  that an update was rolled back, and why.

  The file is `key=value` lines; `NEPTUNUS_FIRMWARE_RECORD` names it (the image sets
  `/data/firmware/last-update`; unset elsewhere).
  """

  @typedoc "The record's fields, by name (`result`, `version`, `running`, `slot`, `reason`, `at`, ...)."
  @type t :: %{optional(String.t()) => String.t()}

  @keys ~w(result version from running slot reason at)

  @doc """
  Parses the record's text: the known keys with a value; other lines are ignored.

      iex> Neptunus.FirmwareRecord.parse("result=rolled-back\\nversion=0.2.0\\nreason=did not boot\\nnoise\\n")
      %{"result" => "rolled-back", "version" => "0.2.0", "reason" => "did not boot"}
      iex> Neptunus.FirmwareRecord.parse("")
      %{}
  """
  @spec parse(String.t()) :: t()
  def parse(text) when is_binary(text) do
    for line <- String.split(text, "\n"),
        [key, value] <- [String.split(line, "=", parts: 2)],
        key in @keys,
        value = String.trim(value),
        value != "",
        into: %{},
        do: {key, String.slice(value, 0, 500)}
  end

  @doc "The record in `path` (nil: none configured), or nil when there is none or it is empty."
  @spec read(Path.t() | nil) :: t() | nil
  def read(nil), do: nil

  def read(path) do
    with {:ok, text} <- File.read(path),
         record when map_size(record) > 0 <- parse(text) do
      record
    else
      _ -> nil
    end
  end
end
