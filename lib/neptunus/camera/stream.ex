defmodule Neptunus.Camera.Stream do
  @moduledoc """
  A camera program's output turned into frames for viewers (pure): the decisions of
  `Neptunus.Vehicle.Camera`, which feeds it the bytes and carries out what it returns.

  `feed/3` cuts the bytes into pictures by the source's format (`Neptunus.Camera.FLV`,
  `Neptunus.Camera.H264` for Annex B, `Neptunus.Camera.MJPEG`) and returns, in order:

    * `{:stream, info}` — a new stream begins: `info` is what viewers need to set up a
      decoder (`t:info/0`, the video WebSocket's `stream` message). Each new stream has a
      new `generation`: the first of a camera program, and a change of picture size or
      codec profile within it (a new SPS, or JPEG images of another size);
    * `{:frame, Neptunus.Camera.Frame.t()}` — one picture, its binary built once.

  An Annex B picture is known complete when the next one's first NAL unit begins (its first
  two bytes tell), an FLV picture when its last byte arrives.

  H.264: a keyframe (IDR picture) always goes out with the SPS and PPS in front of it (ffmpeg
  sends them apart, in the FLV decoder configuration; a camera may send them only once), so
  a viewer can start at any keyframe. Access unit delimiters are dropped; pictures before
  the first keyframe of a stream are dropped too (no decoder can start there) and counted in
  `waiting`. Frames are numbered (`seq`) from 0 in each generation.

  Render stamps: the simulated camera says when it rendered each picture it gave its
  encoder (`stamp/3`, picture index and wall-clock µs); the frame carries it as its capture
  time. The index of an H.264 picture is its FLV timestamp times the frame rate (the
  encoder is fed at a constant rate and drops nothing); of a JPEG, its count.
  """

  alias Neptunus.Camera.{FLV, Frame, H264, MJPEG}
  alias Neptunus.Camera.H264.AccessUnits

  # render stamps older than this many pictures are forgotten
  @stamp_window 120
  # a NAL unit (Annex B) growing past this is not a camera's
  @max_nal_bytes 4_000_000

  @typedoc """
  The stream's description for viewers: `codec` `"h264"` or `"mjpeg"`, the picture size, the
  frame rate (nil when unknown), `generation`, `source` (the source's kind) and `avc` (the
  RFC 6381 codec string, nil for MJPEG).
  """
  @type info :: %{
          codec: String.t(),
          width: pos_integer(),
          height: pos_integer(),
          fps: number() | nil,
          generation: non_neg_integer(),
          source: String.t(),
          avc: String.t() | nil
        }

  @type output :: {:stream, info()} | {:frame, Frame.t()}

  @typedoc """
  * `format`, `source`, `fps` — how the output is cut, the source's kind, its frame rate
  * `demux` — the format's state: an FLV demuxer, `{rest, access units}` for Annex B, the
    JPEG rest for MJPEG
  * `sps`, `pps` — the newest parameter sets (H.264)
  * `info` — the current stream (nil until its first keyframe)
  * `generation` — the current (or, while `info` is nil, the next) stream's generation
  * `seq` — the next frame's number; `pictures` — JPEG images so far (their render index)
  * `stamps` — render times (µs) by picture index, from `stamp/3`
  * `skipped_bytes` — bytes that were not video; `waiting` — pictures dropped before a
    keyframe
  """
  @type t :: %__MODULE__{
          format: Neptunus.Camera.Source.format(),
          source: String.t(),
          fps: pos_integer() | nil,
          demux: term(),
          sps: binary() | nil,
          pps: [binary()],
          info: info() | nil,
          generation: non_neg_integer(),
          seq: non_neg_integer(),
          pictures: non_neg_integer(),
          stamps: %{optional(non_neg_integer()) => non_neg_integer()},
          skipped_bytes: non_neg_integer(),
          waiting: non_neg_integer()
        }
  @enforce_keys [:format, :source, :generation]
  defstruct [
    :format,
    :source,
    :fps,
    :demux,
    :sps,
    :info,
    :generation,
    pps: [],
    seq: 0,
    pictures: 0,
    stamps: %{},
    skipped_bytes: 0,
    waiting: 0
  ]

  @doc """
  A stream at the start of a camera program's output. Options: `:format` (required),
  `:source` (the source's kind, a string), `:fps` (configured, or nil), `:generation` (the
  first stream's).
  """
  @spec new(keyword()) :: t()
  def new(opts) do
    format = Keyword.fetch!(opts, :format)

    %__MODULE__{
      format: format,
      source: Keyword.get(opts, :source, "exec"),
      fps: Keyword.get(opts, :fps),
      generation: Keyword.get(opts, :generation, 0),
      demux: demux(format)
    }
  end

  defp demux(:flv), do: FLV.new()
  defp demux(:annexb), do: {<<>>, AccessUnits.new()}
  defp demux(:mjpeg), do: <<>>

  @doc """
  The stream of the next camera program (after a restart): a new generation, nothing kept
  of the old program's output.
  """
  @spec restart(t()) :: t()
  def restart(%__MODULE__{} = s) do
    next = if s.info == nil and s.seq == 0, do: s.generation, else: s.generation + 1
    new(format: s.format, source: s.source, fps: s.fps, generation: next)
  end

  @doc "Records that picture `index` was rendered at `render_us` (wall-clock µs)."
  @spec stamp(t(), non_neg_integer(), non_neg_integer()) :: t()
  def stamp(%__MODULE__{stamps: stamps} = s, index, render_us) do
    stamps = Map.put(stamps, index, render_us)

    stamps =
      if map_size(stamps) > 2 * @stamp_window,
        do: Map.reject(stamps, fn {i, _} -> i < index - @stamp_window end),
        else: stamps

    %{s | stamps: stamps}
  end

  @doc """
  Adds bytes of the program's output, arrived at `now_us` (wall clock, µs): the streams and
  frames they completed, or `{:error, reason}` for output that cannot be video (the program
  must start again).
  """
  @spec feed(t(), binary(), non_neg_integer()) ::
          {:ok, t(), [output()]} | {:error, String.t()}
  def feed(%__MODULE__{format: :flv, demux: flv} = s, bytes, now_us) do
    with {:ok, flv, events} <- FLV.feed(flv, bytes) do
      {s, out} = Enum.reduce(events, {%{s | demux: flv}, []}, &flv_event(&1, &2, now_us))
      {:ok, s, Enum.reverse(out)}
    end
  end

  def feed(%__MODULE__{format: :annexb, demux: {rest, aus}} = s, bytes, now_us) do
    {nals, rest, skipped} = H264.split(rest <> bytes, byte_size(rest))

    # a NAL unit larger than any picture: not H.264 (drop it, resynchronise at the next one)
    {rest, skipped} =
      if byte_size(rest) > @max_nal_bytes,
        do: {binary_part(rest, byte_size(rest) - 2, 2), skipped + byte_size(rest) - 2},
        else: {rest, skipped}

    {aus, s, out} =
      Enum.reduce(nals, {aus, s, []}, fn nal, {aus, s, out} ->
        aus |> AccessUnits.push(nal) |> access_unit(s, out, now_us)
      end)

    # the next NAL unit's first bytes may already say that the picture before it is whole
    {aus, s, out} = aus |> AccessUnits.next(after_start_code(rest)) |> access_unit(s, out, now_us)

    s = %{s | demux: {rest, aus}, skipped_bytes: s.skipped_bytes + skipped}
    {:ok, s, Enum.reverse(out)}
  end

  def feed(%__MODULE__{format: :mjpeg, demux: rest} = s, bytes, now_us) do
    {jpegs, rest, skipped} = MJPEG.split(rest <> bytes)
    s = %{s | demux: rest, skipped_bytes: s.skipped_bytes + skipped}
    {s, out} = Enum.reduce(jpegs, {s, []}, &jpeg(&1, &2, now_us))
    {:ok, s, Enum.reverse(out)}
  end

  defp access_unit({aus, nil}, s, out, _now_us), do: {aus, s, out}

  defp access_unit({aus, au}, s, out, now_us) do
    {s, out} = picture(s, au, H264.keyframe?(au), nil, now_us, out)
    {aus, s, out}
  end

  defp after_start_code(<<0, 0, 0, 1, head::binary>>), do: head
  defp after_start_code(<<0, 0, 1, head::binary>>), do: head
  defp after_start_code(_rest), do: <<>>

  defp flv_event({:parameter_sets, sps, pps}, {s, out}, _now_us),
    do: {%{s | sps: List.last(sps) || s.sps, pps: if(pps == [], do: s.pps, else: pps)}, out}

  defp flv_event({:picture, nals, keyframe?, ts_ms}, {s, out}, now_us),
    do: picture(s, nals, keyframe?, ts_ms, now_us, out)

  defp flv_event(:end_of_sequence, acc, _now_us), do: acc

  # One H.264 access unit.
  defp picture(s, nals, keyframe?, ts_ms, now_us, out) do
    s = parameter_sets(s, nals)
    keyframe? = keyframe? and H264.keyframe?(nals)
    pictures = Enum.reject(nals, &(H264.type(&1) in [7, 8, 9]))

    cond do
      pictures == [] ->
        {s, out}

      keyframe? and s.sps != nil and s.pps != [] ->
        case h264_info(s) do
          {:ok, info} ->
            {s, out} = announce(s, info, out)
            emit(s, :h264, H264.annexb([s.sps | s.pps] ++ pictures), true, ts_ms, now_us, out)

          {:error, _} ->
            {%{s | waiting: s.waiting + 1}, out}
        end

      s.info != nil and s.info.codec == "h264" and not keyframe? ->
        emit(s, :h264, H264.annexb(pictures), false, ts_ms, now_us, out)

      true ->
        # nothing a decoder could start from yet
        {%{s | waiting: s.waiting + 1}, out}
    end
  end

  # parameter sets sent in band replace the ones known (a new SPS comes with its PPS)
  defp parameter_sets(s, nals) do
    spss = Enum.filter(nals, &(H264.type(&1) == 7))
    ppss = Enum.filter(nals, &(H264.type(&1) == 8))
    %{s | sps: List.last(spss) || s.sps, pps: if(ppss == [], do: s.pps, else: ppss)}
  end

  defp h264_info(s) do
    with {:ok, sps} <- H264.sps(s.sps) do
      {:ok,
       %{
         codec: "h264",
         width: sps.width,
         height: sps.height,
         fps: s.fps || round_fps(sps.fps),
         source: s.source,
         avc: H264.codec_string(s.sps)
       }}
    end
  end

  defp round_fps(nil), do: nil
  defp round_fps(fps), do: if(fps == Float.round(fps), do: trunc(fps), else: fps)

  # One JPEG image.
  defp jpeg(jpeg, {s, out}, now_us) do
    case MJPEG.size(jpeg) do
      {w, h} ->
        info = %{codec: "mjpeg", width: w, height: h, fps: s.fps, source: s.source, avc: nil}
        {s, out} = announce(s, info, out)
        {s, out} = emit(s, :jpeg, jpeg, true, s.pictures, now_us, out)
        {%{s | pictures: s.pictures + 1}, out}

      nil ->
        {%{s | waiting: s.waiting + 1, pictures: s.pictures + 1}, out}
    end
  end

  # A keyframe's description: the same stream goes on, or a new one begins.
  defp announce(%__MODULE__{info: current} = s, info, out) do
    cond do
      current != nil and Map.delete(current, :generation) == info ->
        {s, out}

      current == nil ->
        info = Map.put(info, :generation, s.generation)
        {%{s | info: info, seq: 0}, [{:stream, info} | out]}

      true ->
        info = Map.put(info, :generation, s.generation + 1)
        {%{s | info: info, generation: info.generation, seq: 0}, [{:stream, info} | out]}
    end
  end

  defp emit(s, kind, payload, keyframe?, index, now_us, out) do
    frame =
      Frame.new(kind, payload,
        keyframe: keyframe?,
        first: s.seq == 0,
        generation: s.generation,
        seq: s.seq,
        arrival_us: now_us,
        capture_us: capture_us(s, kind, index)
      )

    {%{s | seq: s.seq + 1}, [{:frame, frame} | out]}
  end

  # the render time of picture `index` (an FLV timestamp in ms for H.264, a count for JPEG)
  defp capture_us(%__MODULE__{stamps: stamps}, _kind, _index) when map_size(stamps) == 0, do: 0
  defp capture_us(_s, _kind, nil), do: 0

  defp capture_us(%__MODULE__{stamps: stamps, fps: fps}, :h264, ts_ms) when is_integer(fps),
    do: Map.get(stamps, round(ts_ms * fps / 1000), 0)

  defp capture_us(%__MODULE__{stamps: stamps}, :jpeg, index), do: Map.get(stamps, index, 0)
  defp capture_us(_s, _kind, _index), do: 0
end
