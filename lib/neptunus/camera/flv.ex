defmodule Neptunus.Camera.FLV do
  @moduledoc """
  H.264 out of an FLV byte stream (what ffmpeg writes with `-f flv`), pure.

  FLV frames every picture as a tag whose length comes first, so a picture is complete the
  moment its last byte arrives — an Annex B stream tells that only when the next picture
  starts (`Neptunus.Camera.H264`), a frame later. The stream: a header (`FLV`, version,
  flags, header size), then tags, each preceded by the size of the tag before it:

      tag: type (8 audio, 9 video, 18 script), data size (24 bits), timestamp (24 bits +
           8 high bits, ms), stream id (24 bits), data
      video data: frame type (4 bits: 1 keyframe, 2 inter frame) | codec (4 bits: 7 AVC),
           packet type (0 decoder configuration, 1 NAL units, 2 end of sequence),
           composition time (24 bits), then the configuration record or the NAL units,
           each after its length (`length_size` bytes, usually 4)

  The decoder configuration (`AVCDecoderConfigurationRecord`, ISO 14496-15) carries the SPS
  and PPS; ffmpeg sends it first, and again when they change.

  `feed/2` returns what the new bytes completed: `{:parameter_sets, sps, pps}` (lists of NAL
  units), `{:picture, nals, keyframe?, timestamp_ms}`, `:end_of_sequence`; or
  `{:error, reason}` for a stream that is not FLV H.264 (the stream cannot be resynchronised:
  start it again).
  """

  import Bitwise

  # a tag larger than any picture a camera sends: the stream is broken
  @max_tag_bytes 8_000_000

  @typedoc """
  * `buffer` — bytes not yet forming a whole tag
  * `header?` — the file header has been read
  * `length_size` — bytes before each NAL unit (from the configuration record)
  """
  @type t :: %__MODULE__{buffer: binary(), header?: boolean(), length_size: 1..4}
  defstruct buffer: <<>>, header?: false, length_size: 4

  @type event ::
          {:parameter_sets, [binary()], [binary()]}
          | {:picture, [binary()], boolean(), non_neg_integer()}
          | :end_of_sequence

  @doc "A demuxer at the start of a stream."
  @spec new() :: t()
  def new, do: %__MODULE__{}

  @doc "Adds bytes; returns the events they completed, in order."
  @spec feed(t(), binary()) :: {:ok, t(), [event()]} | {:error, String.t()}
  def feed(%__MODULE__{} = flv, bytes) when is_binary(bytes) do
    tags(%{flv | buffer: flv.buffer <> bytes}, [])
  end

  defp tags(%{header?: false, buffer: buffer} = flv, acc) do
    case buffer do
      <<"FLV", _version, _flags, size::32, _::binary>> when size >= 9 ->
        if byte_size(buffer) >= size,
          do: tags(%{flv | header?: true, buffer: skip(buffer, size)}, acc),
          else: {:ok, flv, Enum.reverse(acc)}

      <<"FLV", _::binary>> when byte_size(buffer) < 9 ->
        {:ok, flv, Enum.reverse(acc)}

      _ when byte_size(buffer) < 3 ->
        if String.starts_with?("FLV", buffer),
          do: {:ok, flv, Enum.reverse(acc)},
          else: {:error, not_flv(buffer)}

      _ ->
        {:error, not_flv(buffer)}
    end
  end

  defp tags(%{buffer: buffer} = flv, acc) do
    case buffer do
      <<_prev::32, type, size::24, ts::24, ts_high, _stream::24, rest::binary>> ->
        cond do
          size > @max_tag_bytes ->
            {:error, "an FLV tag of #{size} bytes: not a camera's stream"}

          type not in [8, 9, 18] ->
            {:error, "an FLV tag of unknown type #{type}"}

          byte_size(rest) < size ->
            {:ok, flv, Enum.reverse(acc)}

          true ->
            <<data::binary-size(size), rest::binary>> = rest
            flv = %{flv | buffer: rest}
            timestamp = ts_high <<< 24 ||| ts

            case tag(flv, type, data, timestamp) do
              {:ok, flv, nil} -> tags(flv, acc)
              {:ok, flv, event} -> tags(flv, [event | acc])
              {:error, _} = error -> error
            end
        end

      _ ->
        {:ok, flv, Enum.reverse(acc)}
    end
  end

  # video, AVC
  defp tag(flv, 9, <<frame_type::4, 7::4, packet_type, _cts::24, body::binary>>, ts) do
    case packet_type do
      0 ->
        with {:ok, length_size, sps, pps} <- config(body),
             do: {:ok, %{flv | length_size: length_size}, {:parameter_sets, sps, pps}}

      1 ->
        with {:ok, nals} <- nals(body, flv.length_size, []),
             do: {:ok, flv, {:picture, nals, frame_type == 1, ts}}

      2 ->
        {:ok, flv, :end_of_sequence}

      other ->
        {:error, "an FLV AVC packet of unknown type #{other}"}
    end
  end

  defp tag(_flv, 9, <<_frame_type::4, codec::4, _::binary>>, _ts),
    do: {:error, "the FLV stream's video is not H.264 (codec id #{codec})"}

  # audio, script data (metadata) and empty video tags carry no picture
  defp tag(flv, _type, _data, _ts), do: {:ok, flv, nil}

  @doc """
  Reads an `AVCDecoderConfigurationRecord`: the NAL length size and the SPS and PPS.

      iex> record = <<1, 0x42, 0xC0, 0x1E, 0xFF, 0xE1, 3::16, 0x67, 0x42, 0xC0, 1, 2::16, 0x68, 0xCE>>
      iex> Neptunus.Camera.FLV.config(record)
      {:ok, 4, [<<0x67, 0x42, 0xC0>>], [<<0x68, 0xCE>>]}
  """
  @spec config(binary()) :: {:ok, 1..4, [binary()], [binary()]} | {:error, String.t()}
  def config(
        <<1, _profile, _compat, _level, _::6, length_minus_one::2, _::3, n_sps::5, rest::binary>>
      )
      when length_minus_one != 2 do
    with {:ok, sps, <<n_pps, rest::binary>>} <- sets(rest, n_sps, []),
         {:ok, pps, _rest} <- sets(rest, n_pps, []) do
      {:ok, length_minus_one + 1, sps, pps}
    else
      _ -> {:error, "a malformed H.264 decoder configuration"}
    end
  end

  def config(_record), do: {:error, "a malformed H.264 decoder configuration"}

  defp sets(rest, 0, acc), do: {:ok, Enum.reverse(acc), rest}

  defp sets(<<size::16, set::binary-size(size), rest::binary>>, n, acc) when size > 0,
    do: sets(rest, n - 1, [set | acc])

  defp sets(_rest, _n, _acc), do: :error

  defp nals(<<>>, _size, acc), do: {:ok, Enum.reverse(acc)}

  defp nals(body, size, acc) do
    bits = size * 8

    case body do
      <<len::size(bits), nal::binary-size(len), rest::binary>> when len > 0 ->
        nals(rest, size, [nal | acc])

      <<0::size(bits), rest::binary>> ->
        nals(rest, size, acc)

      _ ->
        {:error, "a malformed FLV picture (NAL unit lengths do not add up)"}
    end
  end

  @doc """
  An FLV stream's beginning: the header (video only) and the first previous-tag-size.
  With `tag/4`, what tests and tools need to write one.
  """
  @spec header() :: binary()
  def header, do: <<"FLV", 1, 1, 9::32, 0::32>>

  @doc """
  One FLV tag (with the previous-tag-size after it) carrying a decoder configuration
  (`{:config, sps, pps}`) or a picture (`{:picture, nals, keyframe?}`) at `timestamp_ms`.
  """
  @spec tag(
          {:config, [binary()], [binary()]} | {:picture, [binary()], boolean()},
          non_neg_integer()
        ) ::
          binary()
  def tag({:config, [first | _] = sps, pps}, timestamp_ms) do
    <<_, profile, compat, level, _::binary>> = first

    record =
      IO.iodata_to_binary([
        <<1, profile, compat, level, 0xFF, 0xE0 ||| length(sps)>>,
        Enum.map(sps, &<<byte_size(&1)::16, &1::binary>>),
        <<length(pps)>>,
        Enum.map(pps, &<<byte_size(&1)::16, &1::binary>>)
      ])

    video_tag(<<0x17, 0, 0::24, record::binary>>, timestamp_ms)
  end

  def tag({:picture, nals, keyframe?}, timestamp_ms) do
    frame_type = if keyframe?, do: 1, else: 2
    body = IO.iodata_to_binary(Enum.map(nals, &<<byte_size(&1)::32, &1::binary>>))
    video_tag(<<frame_type::4, 7::4, 1, 0::24, body::binary>>, timestamp_ms)
  end

  defp video_tag(data, ts) do
    size = byte_size(data)
    tag = <<9, size::24, ts &&& 0xFFFFFF::24, ts >>> 24 &&& 0xFF, 0::24, data::binary>>
    <<tag::binary, byte_size(tag)::32>>
  end

  defp skip(buffer, n), do: binary_part(buffer, n, byte_size(buffer) - n)

  defp not_flv(buffer) do
    "the camera program's output is not FLV (it begins " <>
      inspect(binary_part(buffer, 0, min(8, byte_size(buffer))), base: :hex) <> ")"
  end
end
