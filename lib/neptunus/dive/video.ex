defmodule Neptunus.Dive.Video do
  @moduledoc """
  A dive's video on disk: the camera's frames as received (H.264 access units in Annex B, or
  JPEG images; never re-encoded), in segments, each with an index of its frames' times. The
  recorder's video writer (`Neptunus.Vehicle.Recorder.Video`) writes them; this module is the
  format (pure) and its reader.

      <dive>/video/000001.h264   the access units, one after the other (Annex B): any H.264
                                 player plays it; it starts with a keyframe, SPS and PPS in
                                 front, as every keyframe of the camera's stream
      <dive>/video/000001.idx    its index (below)
      <dive>/video/000002.mjpeg  an MJPEG camera's segment: the JPEG images one after the other

  A segment begins at a keyframe: at the first frame recorded, at each new stream of the
  camera (a restart, a new picture size: a new `generation`) and at the first keyframe once
  the segment has lasted `segment_us` or grown to `segment_bytes` (`Recorder.Video`).

  The index: `"NEPVIDX1"`, a 32-bit big-endian length and the stream's description as JSON
  (`codec`, `width`, `height`, `fps`, `avc`, `generation`, `source`, `first_seq`), then one
  #{32}-byte record per frame:

      offset size
      0      8    arrival: wall-clock µs since the epoch when the server cut the frame (the
                  dive's time base: telemetry entries carry the same clock, in ms)
      8      8    capture/render time, wall-clock µs, 0 when the source does not say
      16     8    the frame's offset in the segment file
      24     4    its size in bytes
      28     1    flags: bit 0 keyframe
      29     3    zero

  Both files only grow, and are synced (data, then index) every half second at most, so a
  node killed mid-write leaves a torn index record or frame at the end at worst: `read/1`
  reads what is whole (a record whose frame is not all on disk is dropped) and says what it
  left out.
  """

  import Bitwise

  @magic "NEPVIDX1"
  @record_bytes 32

  @typedoc "One recorded frame, as its index says."
  @type frame :: %{
          at_us: non_neg_integer(),
          capture_us: non_neg_integer(),
          offset: non_neg_integer(),
          size: non_neg_integer(),
          keyframe: boolean()
        }

  @typedoc """
  A segment as read: its number, its files, the stream's description (`info`, string keys as
  in the index), its frames, its first and last frame's arrival (µs), and `problems`: what
  could not be read, in words (a torn end, a missing file).
  """
  @type segment :: %{
          n: pos_integer(),
          data: Path.t(),
          index: Path.t(),
          codec: String.t(),
          info: map(),
          frames: [frame()],
          first_us: non_neg_integer() | nil,
          last_us: non_neg_integer() | nil,
          bytes: non_neg_integer(),
          problems: [String.t()]
        }

  @doc "The size of one index record."
  @spec record_bytes() :: pos_integer()
  def record_bytes, do: @record_bytes

  @doc """
  A segment's file names in the video folder, by number and codec.

      iex> Neptunus.Dive.Video.names(3, "h264")
      {"000003.h264", "000003.idx"}
      iex> Neptunus.Dive.Video.names(12, "mjpeg")
      {"000012.mjpeg", "000012.idx"}
  """
  @spec names(pos_integer(), String.t()) :: {String.t(), String.t()}
  def names(n, codec) when codec in ["h264", "mjpeg"] do
    base = n |> Integer.to_string() |> String.pad_leading(6, "0")
    {"#{base}.#{codec}", "#{base}.idx"}
  end

  @doc """
  The index header of a segment of the stream `info` (a camera's `Neptunus.Camera.Stream`
  info; atom or string keys).

      iex> header = Neptunus.Dive.Video.header(%{codec: "mjpeg", width: 4, height: 2, fps: nil})
      iex> {:ok, info, ""} = Neptunus.Dive.Video.parse_header(header)
      iex> info["codec"]
      "mjpeg"
  """
  @spec header(map()) :: binary()
  def header(info) do
    json = Neptunus.JSON.encode!(info)
    <<@magic, byte_size(json)::32, json::binary>>
  end

  @doc "Reads an index's header: the stream's description and the records after it."
  @spec parse_header(binary()) :: {:ok, map(), binary()} | {:error, String.t()}
  def parse_header(<<@magic, len::32, json::binary-size(len), records::binary>>) do
    case Neptunus.JSON.decode(json) do
      {:ok, %{"codec" => codec} = info} when codec in ["h264", "mjpeg"] -> {:ok, info, records}
      {:ok, _} -> {:error, "the index does not say the codec"}
      {:error, reason} -> {:error, "the index header is not JSON: #{reason}"}
    end
  end

  def parse_header(<<@magic, _::binary>>), do: {:error, "the index header is cut off"}
  def parse_header(_), do: {:error, "not a video index (no NEPVIDX1 header)"}

  @doc """
  One index record.

      iex> record = Neptunus.Dive.Video.record(%{at_us: 5, capture_us: 0, offset: 10, size: 3, keyframe: true})
      iex> byte_size(record)
      32
      iex> Neptunus.Dive.Video.parse_records(record)
      {[%{at_us: 5, capture_us: 0, offset: 10, size: 3, keyframe: true}], 0}
  """
  @spec record(frame()) :: binary()
  def record(%{at_us: at, capture_us: capture, offset: offset, size: size, keyframe: key}) do
    <<at::64, capture::64, offset::64, size::32, if(key, do: 1, else: 0)::8, 0::24>>
  end

  @doc """
  The records of an index (after its header), in order, and the bytes of a torn last record
  left over.
  """
  @spec parse_records(binary()) :: {[frame()], non_neg_integer()}
  def parse_records(bytes), do: parse_records(bytes, [])

  defp parse_records(
         <<at::64, capture::64, offset::64, size::32, flags::8, _::24, rest::binary>>,
         acc
       ) do
    frame = %{
      at_us: at,
      capture_us: capture,
      offset: offset,
      size: size,
      keyframe: (flags &&& 1) == 1
    }

    parse_records(rest, [frame | acc])
  end

  defp parse_records(rest, acc), do: {Enum.reverse(acc), byte_size(rest)}

  @doc "The numbers of the segments in a dive's video folder, in order."
  @spec numbers(Path.t()) :: [pos_integer()]
  def numbers(folder) do
    case File.ls(folder) do
      {:ok, names} ->
        names
        |> Enum.flat_map(fn name ->
          case Regex.run(~r/\A(\d{6})\.(h264|mjpeg|idx)\z/, name) do
            [_, n, _ext] -> [String.to_integer(n)]
            nil -> []
          end
        end)
        |> Enum.uniq()
        |> Enum.sort()

      {:error, _} ->
        []
    end
  end

  @doc """
  The segments in a dive's video folder, in order, each read with `read/2` (an empty list
  when the dive has no video). Files that are not a segment's are left alone.
  """
  @spec segments(Path.t()) :: [segment()]
  def segments(folder), do: folder |> numbers() |> Enum.map(&read(folder, &1))

  @doc """
  Reads segment `n` of a video folder: its index, checked against its data file. A record
  whose frame is not all in the data file (a node killed mid-write), records out of order
  and a torn last record are left out, and said in `problems`; so is a missing or unreadable
  file (the segment then has no frames).
  """
  @spec read(Path.t(), pos_integer()) :: segment()
  def read(folder, n) do
    index = Path.join(folder, names(n, "h264") |> elem(1))

    base = %{
      n: n,
      data: nil,
      index: index,
      codec: nil,
      info: %{},
      frames: [],
      first_us: nil,
      last_us: nil,
      bytes: 0,
      problems: []
    }

    with {:ok, bytes} <- read_index(index),
         {:ok, info, records} <- parse_header(bytes),
         codec = info["codec"],
         data = Path.join(folder, elem(names(n, codec), 0)),
         {:ok, size} <- data_size(data) do
      {frames, torn} = parse_records(records)
      {frames, dropped} = whole(frames, size)

      problems =
        [
          torn > 0 && "segment #{n}: a torn index record at its end (#{torn} bytes)",
          dropped > 0 &&
            "segment #{n}: #{dropped} #{plural(dropped, "frame")} not (all) in #{Path.basename(data)}"
        ]
        |> Enum.filter(& &1)

      %{
        base
        | data: data,
          codec: codec,
          info: info,
          frames: frames,
          first_us: frames |> List.first() |> at_us(),
          last_us: frames |> List.last() |> at_us(),
          bytes: size,
          problems: problems
      }
    else
      {:error, reason} -> %{base | problems: ["segment #{n}: #{reason}"]}
    end
  end

  defp at_us(nil), do: nil
  defp at_us(%{at_us: at}), do: at

  defp read_index(path) do
    case File.read(path) do
      {:ok, bytes} ->
        {:ok, bytes}

      {:error, :enoent} ->
        {:error, "no index (#{Path.basename(path)} is missing)"}

      {:error, reason} ->
        {:error, "cannot read #{Path.basename(path)}: #{:file.format_error(reason)}"}
    end
  end

  defp data_size(path) do
    case File.stat(path) do
      {:ok, %File.Stat{type: :regular, size: size}} ->
        {:ok, size}

      {:ok, _} ->
        {:error, "#{Path.basename(path)} is not a file"}

      {:error, :enoent} ->
        {:error, "#{Path.basename(path)} is missing"}

      {:error, reason} ->
        {:error, "cannot read #{Path.basename(path)}: #{:file.format_error(reason)}"}
    end
  end

  # the records whose frames are wholly in the data file, in time order
  defp whole(frames, size) do
    {kept, dropped, _last} =
      Enum.reduce(frames, {[], 0, -1}, fn f, {kept, dropped, last} ->
        if f.offset + f.size <= size and f.at_us >= last,
          do: {[f | kept], dropped, f.at_us},
          else: {kept, dropped + 1, last}
      end)

    {Enum.reverse(kept), dropped}
  end

  defp plural(1, word), do: word
  defp plural(_, word), do: word <> "s"

  @doc """
  The frames of segments `numbers` of a video folder with their payloads, lazily and in
  order: `{segment, frame, payload}`, `segment` without its frame list. One segment's index
  is read at a time and its file frame by frame, so memory holds one segment's index and one
  frame. A segment whose file went away or shrank since it was indexed ends early.
  """
  @spec frames(Path.t(), [pos_integer()]) :: Enumerable.t()
  def frames(folder, numbers) do
    Stream.flat_map(numbers, fn n ->
      case read(folder, n) do
        %{frames: []} -> []
        segment -> payloads(segment)
      end
    end)
  end

  @doc "The frames of one segment (as `read/2` gives it) with their payloads, lazily."
  @spec payloads(segment()) :: Enumerable.t()
  def payloads(%{frames: frames} = segment) do
    meta = %{segment | frames: []}

    Stream.resource(
      fn -> {open(segment.data), frames} end,
      fn
        {nil, _} ->
          {:halt, {nil, []}}

        {_fd, []} = acc ->
          {:halt, acc}

        {fd, [frame | rest]} ->
          case :file.pread(fd, frame.offset, frame.size) do
            {:ok, payload} when byte_size(payload) == frame.size ->
              {[{meta, frame, payload}], {fd, rest}}

            _ ->
              {:halt, {fd, []}}
          end
      end,
      fn
        {nil, _} -> :ok
        {fd, _} -> :file.close(fd)
      end
    )
  end

  defp open(path) do
    case :file.open(path, [:read, :raw, :binary]) do
      {:ok, fd} -> fd
      {:error, _} -> nil
    end
  end

  @doc """
  From `segments`, the frames to decode to show the picture at `at_us`, up to `to_us`: from
  the last keyframe at or before `at_us` (the first keyframe when none is before) to the last
  frame at or before `to_us`. As `{segment, frames}` pairs, segments in order.
  """
  @spec window([segment()], non_neg_integer(), non_neg_integer()) :: [{segment(), [frame()]}]
  def window(segments, at_us, to_us) do
    keyed = for s <- segments, f <- s.frames, f.keyframe, f.at_us <= at_us, do: {s.n, f.at_us}

    {start_n, start_us} =
      case List.last(keyed) do
        nil -> {0, 0}
        key -> key
      end

    segments
    |> Enum.filter(&(&1.n >= start_n))
    |> Enum.map(fn s ->
      frames =
        Enum.filter(s.frames, fn f ->
          (s.n > start_n or f.at_us >= start_us) and f.at_us <= to_us
        end)

      {s, frames}
    end)
    |> Enum.reject(fn {_s, frames} -> frames == [] end)
  end
end
