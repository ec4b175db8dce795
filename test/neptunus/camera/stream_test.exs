defmodule Neptunus.Camera.StreamTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.Camera.{FLV, Frame, H264, Stream}
  alias Neptunus.Test.H264Gen

  doctest FLV

  @frame1 File.read!("test/fixtures/camera/frame1.jpg")
  @frame2 File.read!("test/fixtures/camera/frame2.jpg")
  # the SPS of x264's 1920x1080 high profile
  @big_sps Base.decode16!("67640028ACD940780227E5C044000003000400000300C83C60C658")

  # what ffmpeg's FLV holds: the parameter sets in the configuration, not in the pictures
  defp flv(aus, config \\ [H264Gen.sps()]) do
    tags =
      aus
      |> Enum.with_index()
      |> Enum.map(fn {au, i} ->
        pictures = Enum.reject(au, &(H264.type(&1) in [7, 8, 9]))
        FLV.tag({:picture, pictures, H264.keyframe?(au)}, i * 33)
      end)

    IO.iodata_to_binary([FLV.header(), FLV.tag({:config, config, [H264Gen.pps()]}, 0) | tags])
  end

  defp feed_all(stream, chunks, now_us \\ 1_000) do
    Enum.reduce(chunks, {stream, []}, fn chunk, {stream, out} ->
      {:ok, stream, new} = Stream.feed(stream, chunk, now_us)
      {stream, out ++ new}
    end)
  end

  defp frames(outputs), do: for({:frame, frame} <- outputs, do: frame)

  defp new(format, opts \\ []),
    do:
      Stream.new(Keyword.merge([format: format, source: "testsrc", fps: 30, generation: 7], opts))

  test "FLV: one frame per picture, keyframes with SPS and PPS in front, whatever the chunking" do
    check(
      H264Gen.stream_and_cuts(),
      fn {aus, _annexb, cuts} ->
        bytes = flv(aus)
        {stream, outputs} = feed_all(new(:flv), H264Gen.chunks(bytes, cuts))

        [{:stream, info} | _] = outputs
        frames = frames(outputs)

        info == %{
          codec: "h264",
          width: 640,
          height: 360,
          fps: 30,
          generation: 7,
          source: "testsrc",
          avc: "avc1.42C01E"
        } and length(frames) == length(aus) and
          Enum.map(frames, & &1.seq) == Enum.to_list(0..(length(aus) - 1)) and
          Enum.all?(Enum.zip(frames, aus), fn {frame, au} ->
            pictures = Enum.reject(au, &(H264.type(&1) in [7, 8, 9]))
            params = if frame.keyframe, do: [H264Gen.sps(), H264Gen.pps()], else: []

            frame.keyframe == H264.keyframe?(au) and frame.generation == 7 and
              Frame.payload(frame) == IO.iodata_to_binary(H264.annexb(params ++ pictures))
          end) and hd(frames).data |> Frame.parse() |> elem(1) |> Map.fetch!(:first) and
          stream.waiting == 0
      end,
      200
    )
  end

  test "Annex B: the same frames, each known complete when the next picture starts" do
    check(
      H264Gen.stream_and_cuts(),
      fn {aus, bytes, cuts} ->
        {_stream, outputs} = feed_all(new(:annexb), H264Gen.chunks(bytes, cuts))
        frames = frames(outputs)
        # the last picture waits for the next one
        length(frames) == length(aus) - 1 and
          Enum.all?(Enum.zip(frames, aus), fn {frame, au} ->
            payload = Frame.payload(frame)
            # keyframes: SPS and PPS first; the delimiters gone
            frame.keyframe == H264.keyframe?(au) and
              (not frame.keyframe or
                 String.starts_with?(payload, IO.iodata_to_binary(H264.annexb([H264Gen.sps()])))) and
              not String.contains?(payload, <<0, 0, 0, 1, 0x09>>)
          end)
      end,
      200
    )
  end

  test "a camera that sends its parameter sets once: every later keyframe gets them" do
    [key | _] =
      aus = [
        [H264Gen.sps(), H264Gen.pps(), <<0x65, 0x88, 1>>],
        [<<0x41, 0x9A, 2>>],
        [<<0x65, 0x88, 3>>],
        [<<0x41, 0x9A, 4>>]
      ]

    bytes = aus |> List.flatten() |> H264.annexb() |> IO.iodata_to_binary()
    {_stream, outputs} = feed_all(new(:annexb), [bytes])
    [first, _, third] = frames(outputs)
    assert Frame.payload(first) == IO.iodata_to_binary(H264.annexb(key))

    assert Frame.payload(third) ==
             IO.iodata_to_binary(H264.annexb([H264Gen.sps(), H264Gen.pps(), <<0x65, 0x88, 3>>]))
  end

  test "pictures before the first keyframe are dropped and counted; frames start at it" do
    aus = [
      [<<0x41, 0x9A, 1>>],
      [<<0x41, 0x9A, 2>>],
      [H264Gen.sps(), H264Gen.pps(), <<0x65, 0x88>>],
      [<<0x41, 0x9A, 3>>]
    ]

    bytes = flv(aus)
    {stream, outputs} = feed_all(new(:flv), [bytes])

    assert [
             {:stream, _},
             {:frame, %{keyframe: true, seq: 0}},
             {:frame, %{keyframe: false, seq: 1}}
           ] = outputs

    assert stream.waiting == 2
  end

  test "a new picture size: a new generation at its keyframe, announced before it" do
    small = [[H264Gen.sps(), H264Gen.pps(), <<0x65, 0x88, 1>>], [<<0x41, 0x9A, 2>>]]
    big = [[@big_sps, H264Gen.pps(), <<0x65, 0x88, 3>>], [<<0x41, 0x9A, 4>>]]
    bytes = (small ++ big) |> List.flatten() |> H264.annexb() |> IO.iodata_to_binary()
    {stream, outputs} = feed_all(new(:annexb), [bytes, <<0, 0, 0, 1, 0x65, 0x88, 5>>])

    assert [
             {:stream, %{width: 640, generation: 7}},
             {:frame, %{generation: 7, seq: 0}},
             {:frame, %{generation: 7, seq: 1}},
             {:stream, %{width: 1920, height: 1080, generation: 8, avc: "avc1.640028"}},
             {:frame, %{generation: 8, seq: 0, keyframe: true} = first},
             {:frame, %{generation: 8, seq: 1}}
           ] = outputs

    assert {:ok, %{first: true}} = Frame.parse(first.data)
    # after a restart: the next generation, nothing kept
    restarted = Stream.restart(stream)
    assert restarted.generation == 9 and restarted.info == nil and restarted.sps == nil
    # a program that stopped before its first picture does not use up a generation
    assert Stream.restart(restarted).generation == 9
  end

  test "render stamps: an H.264 picture's capture time is its picture's render time" do
    aus = [[H264Gen.sps(), H264Gen.pps(), <<0x65, 0x88>>], [<<0x41, 0x9A>>], [<<0x41, 0x9B>>]]
    stream = new(:flv) |> Stream.stamp(0, 111) |> Stream.stamp(1, 222) |> Stream.stamp(2, 333)
    # ffmpeg stamps picture i at round(i * 1000 / 30) ms
    bytes =
      IO.iodata_to_binary([
        FLV.header(),
        FLV.tag({:config, [H264Gen.sps()], [H264Gen.pps()]}, 0)
        | for(
            {au, ts} <- Enum.zip(aus, [0, 33, 67]),
            do: FLV.tag({:picture, au -- [H264Gen.sps(), H264Gen.pps()], ts == 0}, ts)
          )
      ])

    {_stream, outputs} = feed_all(stream, [bytes], 999)

    assert for(
             f <- frames(outputs),
             do: Frame.parse(f.data) |> elem(1) |> Map.take([:capture_us, :arrival_us])
           ) ==
             [
               %{capture_us: 111, arrival_us: 999},
               %{capture_us: 222, arrival_us: 999},
               %{capture_us: 333, arrival_us: 999}
             ]
  end

  test "MJPEG: every image a keyframe, its size the stream's; a new size a new generation" do
    {_stream, outputs} =
      feed_all(new(:mjpeg, fps: nil) |> Stream.stamp(1, 55), [@frame1 <> @frame2, "junk"])

    {w, h} = Neptunus.Camera.MJPEG.size(@frame1)

    assert [
             {:stream, %{codec: "mjpeg", width: ^w, height: ^h, avc: nil, fps: nil}},
             {:frame, %{keyframe: true, seq: 0} = a},
             {:frame, %{keyframe: true, seq: 1} = b}
           ] = outputs

    assert Frame.payload(a) == @frame1 and Frame.payload(b) == @frame2
    assert {:ok, %{kind: :jpeg, capture_us: 55}} = Frame.parse(b.data)

    bigger = <<0xFF, 0xD8, 0xFF, 0xC0, 0, 11, 8, 480::16, 640::16, 1, 1, 0x11, 0, 0xFF, 0xD9>>
    {_stream, outputs} = feed_all(new(:mjpeg), [@frame1, bigger])

    assert [
             {:stream, %{generation: 7}},
             {:frame, _},
             {:stream, %{width: 640, generation: 8}},
             {:frame, _}
           ] = outputs
  end

  test "not FLV, a broken FLV picture, a giant tag: an error (the program starts again)" do
    assert {:error, "the camera program's output is not FLV" <> _} =
             Stream.feed(new(:flv), "GARBAGE!", 0)

    broken = FLV.header() <> FLV.tag({:picture, [<<0x65, 1>>], true}, 0)
    <<head::binary-size(byte_size(broken) - 6), _::binary>> = broken
    # a NAL length beyond the tag: cut the tag's body short by rewriting its size
    assert {:ok, _, []} = Stream.feed(new(:flv), head, 0)

    giant = FLV.header() <> <<0::32, 9, 0xFFFFFF::24, 0::32, 0::24>>
    assert {:error, "an FLV tag of " <> _} = Stream.feed(new(:flv), giant, 0)

    check(:proper_types.binary(), fn bytes ->
      match?({_, _, _}, Stream.feed(new(:flv), FLV.header() <> bytes, 0)) or
        match?({:error, _}, Stream.feed(new(:flv), FLV.header() <> bytes, 0))
    end)
  end

  test "Annex B garbage never crashes; a NAL unit past 4 MB is dropped" do
    check(:proper_types.binary(), fn bytes ->
      match?({:ok, _, _}, Stream.feed(new(:annexb), bytes, 0))
    end)

    {:ok, stream, []} =
      Stream.feed(new(:annexb), <<0, 0, 1, 0x65>> <> :binary.copy(<<7>>, 4_100_000), 0)

    {rest, _} = stream.demux
    assert byte_size(rest) <= 3 and stream.skipped_bytes > 4_000_000
  end
end
