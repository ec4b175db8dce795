defmodule Neptunus.Camera.MJPEGTest do
  use ExUnit.Case, async: true

  alias Neptunus.Camera.MJPEG

  doctest MJPEG

  @frame1 File.read!("test/fixtures/camera/frame1.jpg")
  @frame2 File.read!("test/fixtures/camera/frame2.jpg")

  # feeds `chunks` one after the other as a camera program's output would arrive
  defp feed(chunks, max \\ 4_000_000) do
    Enum.reduce(chunks, {[], <<>>, 0}, fn chunk, {frames, rest, skipped} ->
      {new, rest, s} = MJPEG.split(rest <> chunk, max)
      {frames ++ new, rest, skipped + s}
    end)
  end

  test "real JPEG images (with an ICC profile) come out whole, whatever the chunking" do
    stream = @frame1 <> @frame2 <> @frame1
    assert feed([stream]) == {[@frame1, @frame2, @frame1], <<>>, 0}

    # every split point of two frames into two chunks
    two = @frame1 <> @frame2

    for cut <- 0..byte_size(two) do
      <<a::binary-size(cut), b::binary>> = two
      assert feed([a, b]) == {[@frame1, @frame2], <<>>, 0}, "cut at #{cut}"
    end

    # byte by byte
    assert feed(for <<byte <- two>>, do: <<byte>>) == {[@frame1, @frame2], <<>>, 0}
  end

  test "FF D9 inside a segment does not end the frame" do
    app = <<0xFF, 0xE1, 0, 6, 0xFF, 0xD9, 0xFF, 0xD9>>

    frame =
      <<0xFF, 0xD8>> <> app <> <<0xFF, 0xDA, 0, 2, 7, 0xFF, 0x00, 0xFF, 0xD3, 8, 0xFF, 0xD9>>

    assert MJPEG.split(frame) == {[frame], <<>>, 0}
  end

  test "garbage before, between and after frames is skipped and counted" do
    {frames, rest, skipped} = feed(["noise", @frame1, "xx", @frame2, "tail"])
    assert frames == [@frame1, @frame2]
    assert rest == <<>>
    assert skipped == 5 + 2 + 4
    # a trailing FF may start the next frame: kept
    assert MJPEG.split("ab" <> <<0xFF>>) == {[], <<0xFF>>, 2}
    assert MJPEG.split(<<>>) == {[], <<>>, 0}
  end

  test "a broken frame is dropped and the stream resynchronises at the next one" do
    truncated = binary_part(@frame1, 0, 700)
    {frames, rest, skipped} = feed([truncated, @frame2])
    assert frames == [@frame2]
    assert rest == <<>>
    assert skipped == 700

    # not a marker where one must be
    bad = <<0xFF, 0xD8, 0x12, 0x34>> <> @frame2
    assert {[@frame2], <<>>, 4} = MJPEG.split(bad)
  end

  test "a frame growing past max_bytes is dropped, not buffered forever" do
    endless = <<0xFF, 0xD8, 0xFF, 0xDA, 0, 2>> <> :binary.copy(<<1>>, 5_000)
    {frames, rest, skipped} = feed([endless, @frame1], 4_000)
    assert frames == [@frame1]
    assert rest == <<>>
    assert skipped == byte_size(endless)
  end
end
