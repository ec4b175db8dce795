defmodule Neptunus.Test.PyMAVLink do
  @moduledoc """
  Runs pymavlink's side of the MAVLink interoperability tests (`test/support/pymavlink_interop.py`)
  with the project's virtualenv (`.venv/`, made by `make setup` with the pinned pymavlink) and
  returns its JSON answer; converts values between that JSON and the codec's terms (char
  strings travel as `{"hex": ...}`, NaN and infinities as strings).
  """

  import ExUnit.Assertions

  alias Neptunus.Protocol.MAVLink.Messages

  @root Path.expand("../..", __DIR__)
  @script Path.join(@root, "test/support/pymavlink_interop.py")

  @doc "The virtualenv's Python, or a test failure that says how to make it."
  @spec python!() :: String.t()
  def python! do
    python = Path.join(@root, ".venv/bin/python")

    unless File.exists?(python),
      do: flunk("#{python} is missing: run `make setup` (it installs pymavlink into .venv/)")

    python
  end

  @doc "Runs the script with `args`; its decoded JSON answer (maps with string keys)."
  @spec run!([String.t()]) :: term()
  def run!(args) do
    {output, status} =
      System.cmd(python!(), [@script | args], env: [{"MAVLINK20", "1"}], stderr_to_stdout: true)

    assert status == 0, "pymavlink_interop.py #{Enum.join(args, " ")} failed:\n#{output}"
    :jiffy.decode(output, [:return_maps])
  end

  @doc "A JSON fields map of `message` as the codec's fields (atom keys, its value terms)."
  @spec from_json(atom(), map()) :: map()
  def from_json(message, fields) do
    for field <- Messages.get(message).fields, into: %{} do
      {field.name, value(field, Map.fetch!(fields, Atom.to_string(field.name)))}
    end
  end

  defp value(%{type: :char}, %{"hex" => hex}), do: Base.decode16!(hex)

  defp value(%{length: n} = field, list) when is_integer(n),
    do: Enum.map(list, &scalar(field, &1))

  defp value(field, value), do: scalar(field, value)

  defp scalar(_field, "nan"), do: :nan
  defp scalar(_field, "infinity"), do: :infinity
  defp scalar(_field, "neg_infinity"), do: :neg_infinity

  defp scalar(%{type: type}, value) when type in [:float, :double] and is_integer(value),
    do: value * 1.0

  defp scalar(_field, value), do: value
end
