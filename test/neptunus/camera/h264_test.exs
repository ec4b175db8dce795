defmodule Neptunus.Camera.H264Test do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.Camera.H264
  alias Neptunus.Camera.H264.AccessUnits
  alias Neptunus.Test.H264Gen

  doctest H264

  describe "SPS" do
    # SPS of x264's streams: baseline 640x360 (FLV, 30 fps), high 1920x1080 (cropped from
    # 1088), main 352x288, high 4:4:4 1280x720
    @sps [
      {"6742c01eda0280bfe5c04400000300040000030 0f23c58ba80", {66, 0xC0, 30, 640, 360, 30.0},
       "avc1.42C01E"},
      {"67640028acd940780227e5c044000003000400000300c83c60c658", {100, 0, 40, 1920, 1080, 25.0},
       "avc1.640028"},
      {"674d400deca0b04b6022000003000200000300641e28532c", {77, 0x40, 13, 352, 288, 25.0},
       "avc1.4D400D"},
      {"67f4001f919b280a00b76022000003000200000300641e30632c", {244, 0, 31, 1280, 720, 25.0},
       "avc1.F4001F"}
    ]

    test "the size (after cropping), profile, level and frame rate of real SPS" do
      for {hex, {profile, constraints, level, w, h, fps}, codec} <- @sps do
        sps = hex |> String.replace(" ", "") |> Base.decode16!(case: :lower)

        assert H264.sps(sps) ==
                 {:ok,
                  %{
                    profile_idc: profile,
                    constraints: constraints,
                    level_idc: level,
                    width: w,
                    height: h,
                    fps: fps
                  }}

        assert H264.codec_string(sps) == codec
      end
    end

    test "what is not a well-formed SPS is refused, never a crash" do
      assert H264.sps(<<0x68, 1, 2, 3>>) == {:error, "not an SPS"}
      assert H264.sps(<<0x67, 0x42, 0xC0, 0x1E>>) == {:error, "a malformed SPS"}

      check(:proper_types.binary(), fn bytes ->
        match?({_, _}, H264.sps(<<0x67, bytes::binary>>))
      end)
    end
  end

  describe "Annex B" do
    test "escaping and unescaping are inverse" do
      check(:proper_types.binary(), fn raw -> H264.unescape(H264Gen.escape(raw)) == raw end)
    end

    test "access units come out whole and in order, whatever the chunking and start codes" do
      check(
        H264Gen.stream_and_cuts(),
        fn {aus, bytes, cuts} ->
          {out, rest, acc} =
            Enum.reduce(H264Gen.chunks(bytes, cuts), {[], <<>>, AccessUnits.new()}, fn chunk,
                                                                                       {out, rest,
                                                                                        acc} ->
              {nals, rest, 0} = H264.split(rest <> chunk, byte_size(rest))

              {acc, out} =
                Enum.reduce(nals, {acc, out}, fn nal, {acc, out} ->
                  case AccessUnits.push(acc, nal) do
                    {acc, nil} -> {acc, out}
                    {acc, au} -> {acc, [au | out]}
                  end
                end)

              {out, rest, acc}
            end)

          # at the end of the stream the last NAL unit and access unit are flushed
          {acc, out} =
            case H264.flush(rest) do
              nil ->
                {acc, out}

              nal ->
                case AccessUnits.push(acc, nal) do
                  {acc, nil} -> {acc, out}
                  {acc, au} -> {acc, [au | out]}
                end
            end

          {_, last} = AccessUnits.flush(acc)
          Enum.reverse([last | out]) == aus
        end,
        200
      )
    end

    test "bytes before the first start code are skipped and counted; garbage never crashes" do
      assert {[], <<0, 0, 1, 0x65>>, 3} = H264.split(<<1, 2, 3, 0, 0, 1, 0x65>>)
      assert {[], <<0, 0, 0, 1, 0x65>>, 2} = H264.split(<<7, 7, 0, 0, 0, 1, 0x65>>)
      assert {[], <<0, 0>>, 2} = H264.split(<<9, 9, 0, 0>>)
      assert {[], <<0, 0, 0>>, 1} = H264.split(<<9, 0, 0, 0>>)

      check(:proper_types.binary(), fn bytes ->
        {nals, rest, skipped} = H264.split(bytes)
        is_list(nals) and byte_size(rest) + skipped <= byte_size(bytes)
      end)
    end

    test "an access unit begins at a delimiter, parameter sets, SEI, or a picture's first slice" do
      idr = <<0x65, 0x88>>
      second_slice = <<0x65, 0x12>>
      next = <<0x41, 0x9A>>

      {acc, nil} = AccessUnits.push(AccessUnits.new(), <<0x67, 1>>)
      {acc, nil} = AccessUnits.push(acc, <<0x68, 2>>)
      {acc, nil} = AccessUnits.push(acc, idr)
      {acc, nil} = AccessUnits.push(acc, second_slice)
      {acc, [<<0x67, 1>>, <<0x68, 2>>, ^idr, ^second_slice]} = AccessUnits.push(acc, next)
      {acc, [^next]} = AccessUnits.push(acc, <<0x09, 0x10>>)
      assert {_, nil} = AccessUnits.flush(acc)
      assert H264.keyframe?([<<0x67, 1>>, idr]) and not H264.keyframe?([next])
    end
  end
end
