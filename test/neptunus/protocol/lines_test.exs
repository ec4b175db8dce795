defmodule Neptunus.Protocol.LinesTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Protocol.Lines

  import Neptunus.Test.Properties

  alias Neptunus.Protocol.Lines

  defp feed_all(framer, chunks) do
    Enum.reduce(chunks, {[], framer}, fn chunk, {acc, framer} ->
      {lines, framer} = Lines.feed(framer, chunk)
      {acc ++ lines, framer}
    end)
  end

  test "\\n ends a line, \\r is removed, the incomplete tail waits" do
    assert {["a", "b", "", "c"], %Lines{rest: "d"}} = Lines.feed(Lines.new(), "a\r\nb\n\r\nc\nd")
  end

  test "byte by byte gives the same lines" do
    stream = "deap:1;\r\nvout:12;\nx"
    {lines, framer} = feed_all(Lines.new(), for(<<b <- stream>>, do: <<b>>))
    assert lines == ["deap:1;", "vout:12;"]
    assert framer.rest == "x"
  end

  test "an overlong line is dropped and counted, up to its newline, and framing resumes" do
    framer = Lines.new(8)
    {lines, framer} = feed_all(framer, ["ok\n123456", "789", "abc\nnext\n"])
    assert lines == ["ok", "next"]
    assert framer.overlong == 1
    assert framer.rest == ""

    # a complete overlong line in one chunk
    {lines, framer} = Lines.feed(framer, "0123456789\nfine\n")
    assert lines == ["fine"]
    assert framer.overlong == 2
  end

  test "a line of exactly max bytes is kept; memory stays bounded on endless garbage" do
    {["12345678"], _} = Lines.feed(Lines.new(8), "12345678\n")

    framer =
      Enum.reduce(1..1000, Lines.new(64), fn _, framer ->
        {[], framer} = Lines.feed(framer, :binary.copy("x", 100))
        framer
      end)

    assert framer.rest == ""
    assert framer.overlong == 1
  end

  test "property: any lines, cut into any chunks, come out whole and in order" do
    line = bind(:proper_types.binary(), &String.replace(&1, ["\n", "\r"], ""))

    gen =
      bind({:proper_types.list(line), :proper_types.list(:proper_types.integer(1, 40))}, fn
        {lines, cuts} -> {lines, cuts}
      end)

    check(
      gen,
      fn {lines, cuts} ->
        stream = Enum.map_join(lines, &(&1 <> "\r\n"))
        {got, framer} = feed_all(Lines.new(10_000), chunks(stream, cuts))
        got == lines and framer.rest == ""
      end,
      500
    )
  end

  defp chunks("", _cuts), do: []
  defp chunks(stream, []), do: [stream]

  defp chunks(stream, [n | cuts]) do
    n = min(n, byte_size(stream))
    [binary_part(stream, 0, n) | chunks(binary_part(stream, n, byte_size(stream) - n), cuts)]
  end
end
