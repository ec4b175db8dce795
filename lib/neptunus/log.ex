defmodule Neptunus.Log do
  @moduledoc """
  Client-supplied text made safe for the server log.

  Anything a client chooses — a `stop` reason, a display name, a topic, a vehicle id or a
  recording name in a path — may contain a newline or another control character, and
  written to the log as it is it would end the line and forge one that looks like the
  server's own ("…stopped: x\\n12:00:00.000 [info] vehicle alpha: run mode normal"). Every
  place that puts such text into a `Logger` message passes it through `safe/1` first, which
  escapes the C0 and C1 control characters and DEL the way Elixir writes them in strings
  (`\\n`, `\\r`, `\\t`, `\\e`, `\\x7F`, `\\u0085`…) and escapes the backslash, so the log
  line stays one line and is unambiguous. Invalid UTF-8 bytes are shown as `\\xNN`.

      iex> Neptunus.Log.safe("operator\\n12:00:00.000 [info] forged")
      "operator\\\\n12:00:00.000 [info] forged"
      iex> Neptunus.Log.safe("tab\\there, bell\\a, nel\\u0085, back\\\\slash")
      "tab\\\\there, bell\\\\x07, nel\\\\u0085, back\\\\\\\\slash"
      iex> Neptunus.Log.safe(<<"bad ", 0xFF, "byte">>)
      "bad \\\\xFFbyte"
  """

  @doc "`text` (or any term, shown with `to_string/1` or `inspect/1`) with control characters escaped."
  @spec safe(term()) :: String.t()
  def safe(text) when is_binary(text), do: escape(text, [])

  def safe(other) do
    text =
      try do
        to_string(other)
      rescue
        _ -> inspect(other)
      end

    safe(text)
  end

  defp escape(<<>>, acc), do: acc |> Enum.reverse() |> IO.iodata_to_binary()
  defp escape(<<?\\, rest::binary>>, acc), do: escape(rest, ["\\\\" | acc])
  defp escape(<<?\n, rest::binary>>, acc), do: escape(rest, ["\\n" | acc])
  defp escape(<<?\r, rest::binary>>, acc), do: escape(rest, ["\\r" | acc])
  defp escape(<<?\t, rest::binary>>, acc), do: escape(rest, ["\\t" | acc])
  defp escape(<<?\e, rest::binary>>, acc), do: escape(rest, ["\\e" | acc])

  defp escape(<<c::utf8, rest::binary>>, acc) when c < 0x20 or c == 0x7F,
    do: escape(rest, ["\\x" <> hex(c, 2) | acc])

  # C1 controls, and the line and paragraph separators some viewers break lines at
  defp escape(<<c::utf8, rest::binary>>, acc) when c in 0x80..0x9F or c in [0x2028, 0x2029],
    do: escape(rest, ["\\u" <> hex(c, 4) | acc])

  defp escape(<<c::utf8, rest::binary>>, acc), do: escape(rest, [<<c::utf8>> | acc])
  defp escape(<<byte, rest::binary>>, acc), do: escape(rest, ["\\x" <> hex(byte, 2) | acc])

  defp hex(n, width),
    do: n |> Integer.to_string(16) |> String.pad_leading(width, "0")
end
