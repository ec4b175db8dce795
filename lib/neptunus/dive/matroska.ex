defmodule Neptunus.Dive.Matroska do
  @moduledoc """
  A streamed Matroska (EBML) of one video track (pure): the dive's frames with their recorded
  times, for ffmpeg to read and copy into an MP4 (`Neptunus.Dive.Export`), since a raw H.264
  or MJPEG segment carries no times. Written as it goes: the Segment and its Clusters have an
  unknown size (as a live stream's), so nothing is held but the frame at hand.

  Times are in milliseconds (`TimecodeScale` 1 000 000 ns) from `zero_us`; a Cluster begins
  at each keyframe and at least every 30 s (a block's time is a 16-bit offset from its
  cluster's). H.264 goes in as `V_MPEG4/ISO/AVC`: the access unit's NAL units with 4-byte
  lengths instead of start codes, and the SPS and PPS of the first keyframe in
  `CodecPrivate` (an `avcC` record, `avcc/2`); JPEG images as `V_MJPEG`.
  """

  import Bitwise

  alias Neptunus.Camera.H264

  @max_cluster_ms 30_000

  @typedoc "The track: codec, picture size, and for H.264 the SPS and PPS."
  @type track :: %{
          codec: String.t(),
          width: pos_integer() | nil,
          height: pos_integer() | nil,
          sps: binary() | nil,
          pps: [binary()]
        }

  @doc "The file's start: the EBML header, the Segment (unknown size), Info and Tracks."
  @spec header(track()) :: iodata()
  def header(track) do
    ebml =
      element(0x1A45DFA3, [
        uint(0x4286, 1),
        uint(0x42F7, 1),
        uint(0x42F2, 4),
        uint(0x42F3, 8),
        string(0x4282, "matroska"),
        uint(0x4287, 4),
        uint(0x4285, 2)
      ])

    info =
      element(0x1549A966, [
        uint(0x2AD7B1, 1_000_000),
        string(0x4D80, "Neptunus"),
        string(0x5741, "Neptunus")
      ])

    video =
      element(
        0xE0,
        Enum.reject(
          [track.width && uint(0xB0, track.width), track.height && uint(0xBA, track.height)],
          &is_nil/1
        )
      )

    codec =
      case track.codec do
        "h264" -> [string(0x86, "V_MPEG4/ISO/AVC"), binary(0x63A2, avcc(track.sps, track.pps))]
        "mjpeg" -> [string(0x86, "V_MJPEG")]
      end

    entry =
      element(0xAE, [uint(0xD7, 1), uint(0x73C5, 1), uint(0x83, 1), uint(0x9C, 0), codec, video])

    [ebml, id(0x18538067), unknown_size(), info, element(0x1654AE6B, [entry])]
  end

  @doc """
  The blocks of `frames` (`{at_us, keyframe, payload}`, in time order) from `zero_us`,
  lazily, with a Cluster before each keyframe and at least every 30 s. A frame before
  `zero_us` is left out.
  """
  @spec blocks(Enumerable.t(), String.t(), non_neg_integer()) :: Enumerable.t()
  def blocks(frames, codec, zero_us) do
    Stream.transform(frames, nil, fn {at_us, key, payload}, cluster ->
      ms = div(at_us - zero_us + 500, 1000)

      cond do
        at_us < zero_us ->
          {[], cluster}

        cluster == nil or key or ms - cluster > @max_cluster_ms ->
          {[cluster(ms), simple_block(0, key, data(codec, payload))], ms}

        true ->
          {[simple_block(ms - cluster, key, data(codec, payload))], cluster}
      end
    end)
  end

  defp cluster(ms), do: [id(0x1F43B675), unknown_size(), uint(0xE7, ms)]

  defp simple_block(relative_ms, key, data) do
    flags = if key, do: 0x80, else: 0
    binary(0xA3, [<<0x81, relative_ms::signed-16, flags>>, data])
  end

  defp data("mjpeg", jpeg), do: jpeg
  defp data("h264", au), do: au |> nals() |> Enum.map(&<<byte_size(&1)::32, &1::binary>>)

  @doc """
  The NAL units of one Annex B access unit.

      iex> Neptunus.Dive.Matroska.nals(<<0, 0, 0, 1, 0x67, 1, 0, 0, 1, 0x65, 2, 3>>)
      [<<0x67, 1>>, <<0x65, 2, 3>>]
  """
  @spec nals(binary()) :: [binary()]
  def nals(au) do
    {nals, _rest, _skipped} = H264.split(au <> <<0, 0, 1>>)
    nals
  end

  @doc """
  The `avcC` record (ISO 14496-15) of an SPS and its PPSs: 4-byte NAL lengths.

      iex> Neptunus.Dive.Matroska.avcc(<<0x67, 0x42, 0xC0, 0x1E>>, [<<0x68, 0xCE>>])
      <<1, 0x42, 0xC0, 0x1E, 0xFF, 0xE1, 0, 4, 0x67, 0x42, 0xC0, 0x1E, 1, 0, 2, 0x68, 0xCE>>
  """
  @spec avcc(binary(), [binary()]) :: binary()
  def avcc(<<_header, profile, compat, level, _::binary>> = sps, pps) do
    IO.iodata_to_binary([
      <<1, profile, compat, level, 0xFF, 0xE1, byte_size(sps)::16>>,
      sps,
      <<length(pps)>>,
      Enum.map(pps, &[<<byte_size(&1)::16>>, &1])
    ])
  end

  @doc """
  The SPS and PPS of an Annex B keyframe (nil and [] when it has none).

      iex> Neptunus.Dive.Matroska.parameter_sets(<<0, 0, 0, 1, 0x67, 1, 0, 0, 0, 1, 0x68, 2, 0, 0, 1, 0x65, 3>>)
      {<<0x67, 1>>, [<<0x68, 2>>]}
  """
  @spec parameter_sets(binary()) :: {binary() | nil, [binary()]}
  def parameter_sets(au) do
    nals = nals(au)
    {Enum.find(nals, &(H264.type(&1) == 7)), Enum.filter(nals, &(H264.type(&1) == 8))}
  end

  # EBML

  defp element(id, children), do: binary(id, children)

  defp binary(id, data) do
    data = IO.iodata_to_binary(data)
    [id(id), size(byte_size(data)), data]
  end

  defp uint(id, value), do: binary(id, :binary.encode_unsigned(value))
  defp string(id, text), do: binary(id, text)

  defp id(id), do: :binary.encode_unsigned(id)

  # a size as an EBML variable-length integer (8 bytes at most)
  defp size(n) when n < 0x7F, do: <<0x80 ||| n>>
  defp size(n) when n < 0x3FFF, do: <<0x40 ||| n >>> 8, n &&& 0xFF>>
  defp size(n) when n < 0x1FFFFF, do: <<0x20 ||| n >>> 16, n &&& 0xFFFF::16>>
  defp size(n) when n < 0x0FFFFFFF, do: <<0x10 ||| n >>> 24, n &&& 0xFFFFFF::24>>
  defp size(n), do: <<0x01, n::56>>

  defp unknown_size, do: <<0x01, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF>>
end
