defmodule Neptunus.Protocol.Lines do
  @moduledoc """
  Line framing of a byte stream (the board's telemetry): split on `\\n`, remove `\\r`, cap the
  line length. Pure; feed it the chunks as they arrive, in any sizes.

  A line longer than `max` bytes (default #{512}) — a board babbling without newlines, or noise
  on the line — is dropped and counted in `overlong`; the bytes up to the next `\\n` are
  discarded with it, so memory stays bounded whatever the line sends.

      iex> alias Neptunus.Protocol.Lines
      iex> {lines, buf} = Lines.feed(Lines.new(), "deap:1.0;\\r\\nvout:1")
      iex> lines
      ["deap:1.0;"]
      iex> {lines, _buf} = Lines.feed(buf, "2.1;\\n")
      iex> lines
      ["vout:12.1;"]
  """

  @default_max 512

  @enforce_keys [:max]
  defstruct [:max, rest: "", discarding: false, overlong: 0]

  @typedoc """
  * `max` — longest line kept, in bytes as received (`\\r` included)
  * `rest` — bytes of the line in progress
  * `discarding` — inside an overlong line: drop bytes until the next `\\n`
  * `overlong` — overlong lines dropped so far
  """
  @type t :: %__MODULE__{
          max: pos_integer(),
          rest: binary(),
          discarding: boolean(),
          overlong: non_neg_integer()
        }

  @doc "A new framer keeping lines of at most `max` bytes."
  @spec new(pos_integer()) :: t()
  def new(max \\ @default_max) when is_integer(max) and max > 0, do: %__MODULE__{max: max}

  @doc "Feeds a chunk; returns the complete lines in order and the framer for the next chunk."
  @spec feed(t(), binary()) :: {[binary()], t()}
  def feed(%__MODULE__{} = framer, chunk) when is_binary(chunk) do
    {complete, [rest]} = :binary.split(framer.rest <> chunk, "\n", [:global]) |> Enum.split(-1)
    {lines, framer} = Enum.reduce(complete, {[], framer}, &complete_line/2)
    {Enum.reverse(lines), keep_rest(framer, rest)}
  end

  defp complete_line(_tail, {lines, %{discarding: true} = framer}),
    do: {lines, %{framer | discarding: false}}

  defp complete_line(line, {lines, framer}) when byte_size(line) > framer.max,
    do: {lines, %{framer | overlong: framer.overlong + 1}}

  defp complete_line(line, {lines, framer}),
    do: {[:binary.replace(line, "\r", "", [:global]) | lines], framer}

  defp keep_rest(%{discarding: true} = framer, _rest), do: %{framer | rest: ""}

  defp keep_rest(framer, rest) when byte_size(rest) > framer.max,
    do: %{framer | rest: "", discarding: true, overlong: framer.overlong + 1}

  defp keep_rest(framer, rest), do: %{framer | rest: rest}
end
