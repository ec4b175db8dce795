defmodule Neptunus.Test.H264Gen do
  @moduledoc """
  PropEr generators for H.264 streams (`Neptunus.Camera.H264`, `Neptunus.Camera.FLV`,
  `Neptunus.Camera.Stream` tests): access units of well-formed NAL units — escaped payloads,
  keyframes with SPS and PPS, pictures of one or more slices — written as Annex B with 3- or
  4-byte start codes and cut into chunks anywhere.

  The SPS is a real one (x264, baseline 640x360): streams built from it have a size.
  """
  import Bitwise
  import Neptunus.Test.Properties, only: [bind: 2]

  alias :proper_types, as: T

  @sps Base.decode16!(
         "6742C01EDA0280BFE5C04400000300040000030 0F23C58BA80"
         |> String.replace(" ", "")
       )
  @pps <<0x68, 0xCE, 0x0F, 0xC8>>

  @doc "The SPS streams are built with (640x360)."
  @spec sps() :: binary()
  def sps, do: @sps

  @doc "The PPS streams are built with."
  @spec pps() :: binary()
  def pps, do: @pps

  @doc "Emulation prevention: `03` after `00 00` where the next byte is 0..3."
  @spec escape(binary()) :: binary()
  def escape(raw), do: escape(raw, 0, [])

  defp escape(<<>>, _zeros, acc), do: acc |> Enum.reverse() |> IO.iodata_to_binary()

  defp escape(<<b, rest::binary>>, zeros, acc) when zeros >= 2 and b <= 3,
    do: escape(rest, if(b == 0, do: 1, else: 0), [b, 3 | acc])

  defp escape(<<b, rest::binary>>, zeros, acc),
    do: escape(rest, if(b == 0, do: zeros + 1, else: 0), [b | acc])

  # a payload as an encoder writes it: escaped, ending in the stop bit's byte (short: what
  # matters is where zeros and start-code-like bytes fall, not the length)
  defp payload do
    bytes = T.frequency([{3, T.choose(0, 3)}, {1, T.choose(0, 255)}])

    bind(bind(T.choose(0, 40), &T.vector(&1, bytes)), fn raw ->
      escape(:erlang.list_to_binary(raw)) <> <<0x80>>
    end)
  end

  # a slice: type 5 (IDR) or 1; the first of its picture has first_mb_in_slice 0
  defp slice(type, first?) do
    bind(payload(), fn p ->
      lead = if first?, do: 0x80, else: 0x40
      <<0x60 ||| type, lead, p::binary>>
    end)
  end

  @doc "One access unit (a list of NAL units): a keyframe (`true`) or not."
  @spec access_unit(boolean()) :: term()
  def access_unit(keyframe?) do
    type = if keyframe?, do: 5, else: 1

    more = bind(T.choose(0, 3), &T.vector(&1, slice(type, false)))

    bind(
      {T.boolean(), T.boolean(), slice(type, true), more, payload()},
      fn {aud?, sei?, first, more, sei} ->
        head = if aud?, do: [<<0x09, 0xF0>>], else: []
        params = if keyframe?, do: [@sps, @pps], else: []
        sei = if sei?, do: [<<0x06, sei::binary>>], else: []
        head ++ params ++ sei ++ [first | more]
      end
    )
  end

  @doc "A stream of access units starting with a keyframe."
  @spec access_units() :: term()
  def access_units do
    bind(
      {access_unit(true), T.list(T.frequency([{1, access_unit(true)}, {4, access_unit(false)}]))},
      fn {first, rest} -> [first | Enum.take(rest, 12)] end
    )
  end

  @doc "The access units, their Annex B bytes (3- or 4-byte start codes) and cut points."
  @spec stream_and_cuts() :: term()
  def stream_and_cuts do
    cuts = bind(T.choose(0, 8), &T.vector(&1, T.non_neg_integer()))
    longs = bind(T.choose(1, 6), &T.vector(&1, T.boolean()))

    bind({access_units(), longs, cuts}, fn {aus, longs, cuts} ->
      nals = List.flatten(aus)
      longs = Stream.cycle(if longs == [], do: [true], else: longs)

      bytes =
        nals
        |> Enum.zip(longs)
        |> Enum.map(fn {nal, long?} -> [if(long?, do: <<0, 0, 0, 1>>, else: <<0, 0, 1>>), nal] end)
        |> IO.iodata_to_binary()

      {aus, bytes, cuts}
    end)
  end

  @doc "`bytes` cut into chunks at the `cuts` (offsets, taken modulo the size)."
  @spec chunks(binary(), [non_neg_integer()]) :: [binary()]
  def chunks(bytes, cuts) do
    size = byte_size(bytes)
    points = cuts |> Enum.map(&rem(&1, size + 1)) |> Enum.sort() |> Enum.uniq()

    {chunks, last} =
      Enum.map_reduce(points, 0, fn p, from -> {binary_part(bytes, from, p - from), p} end)

    chunks ++ [binary_part(bytes, last, size - last)]
  end
end
