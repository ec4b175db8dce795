defmodule Neptunus.Test.Dives do
  @moduledoc """
  Dives for the tests and the export bench: real H.264 and JPEG frames made by ffmpeg (a
  test pattern), cut into access units as the camera cuts them, and dive folders written
  with the recorder's formats (`Neptunus.Dive`: entries in a `disk_log`, video segments
  with their index, a summary) at chosen times. Uses only the project's code, so
  `bench/dive_export.exs` requires it too.
  """
  alias Neptunus.Camera.{Frame, Stream}
  alias Neptunus.Dive
  alias Neptunus.Dive.{Summary, Video}

  @doc """
  `n` H.264 access units (Annex B, SPS and PPS before each keyframe) of ffmpeg's test
  pattern: `size` (`"160x120"`), `fps`, a keyframe every `gop` pictures, no B-frames.
  """
  @spec h264(pos_integer(), keyword()) :: [binary()]
  def h264(n, opts \\ []) do
    size = Keyword.get(opts, :size, "160x120")
    fps = Keyword.get(opts, :fps, 15)
    gop = Keyword.get(opts, :gop, 15)

    {out, 0} =
      System.cmd(
        ffmpeg!(),
        ~w(-nostdin -hide_banner -loglevel error -f lavfi -i) ++
          ["testsrc=size=#{size}:rate=#{fps}"] ++
          ["-frames:v", "#{n}"] ++
          ~w(-c:v libx264 -pix_fmt yuv420p -preset ultrafast -tune zerolatency -bf 0) ++
          ["-g", "#{gop}", "-keyint_min", "#{gop}", "-sc_threshold", "0"] ++
          ~w(-bsf:v h264_mp4toannexb -f h264 -)
      )

    stream = Stream.new(format: :annexb, source: "testsrc", fps: fps, generation: 1)
    # the last picture is complete once something follows it: an access unit delimiter
    {:ok, _stream, outputs} = Stream.feed(stream, out <> <<0, 0, 0, 1, 0x09, 0xF0>>, 0)
    for {:frame, %Frame{} = f} <- outputs, do: Frame.payload(f)
  end

  @doc "`n` JPEG images of ffmpeg's test pattern (`size`)."
  @spec jpegs(pos_integer(), keyword()) :: [binary()]
  def jpegs(n, opts \\ []) do
    size = Keyword.get(opts, :size, "160x120")

    {out, 0} =
      System.cmd(
        ffmpeg!(),
        ~w(-nostdin -hide_banner -loglevel error -f lavfi -i) ++
          ["testsrc=size=#{size}:rate=15", "-frames:v", "#{n}"] ++
          ~w(-c:v mjpeg -q:v 5 -f mjpeg -)
      )

    {jpegs, _rest, _skipped} = Neptunus.Camera.MJPEG.split(out)
    jpegs
  end

  @doc "Whether an H.264 access unit holds an IDR picture."
  @spec keyframe?(binary()) :: boolean()
  def keyframe?(au),
    do: au |> Dive.Matroska.nals() |> Neptunus.Camera.H264.keyframe?()

  @doc """
  What the `mcap` package (PyPI, in the project's `.venv`) reads from an MCAP file
  (`test/support/mcap_read.py`), as a map.
  """
  @spec mcap_read!(Path.t()) :: map()
  def mcap_read!(file) do
    root = Path.expand("../..", __DIR__)
    python = Path.join(root, ".venv/bin/python")
    unless File.exists?(python), do: raise("#{python} is missing: run `make setup` (mcap)")

    case System.cmd(python, [Path.join(root, "test/support/mcap_read.py"), file],
           stderr_to_stdout: true
         ) do
      {out, 0} -> :jiffy.decode(out, [:return_maps])
      {out, _} -> raise "the mcap reader failed:\n#{out}"
    end
  end

  defp ffmpeg!, do: System.find_executable("ffmpeg") || raise("ffmpeg is not installed")

  @doc """
  Writes a dive folder `<dir>/<vehicle>/<name>` as the recorder would: `entries`
  (`{at_ms, event, payload}`) into `entries-0001.log`, `frames` (`{at_us, keyframe,
  payload}`, of `codec`) into video segments of `segment_frames` frames each (a new one at
  the first keyframe after that), and `summary.json` (closed unless `closed: false`).
  Returns the folder.
  """
  @spec write!(Path.t(), String.t(), String.t(), Enumerable.t(), Enumerable.t(), keyword()) ::
          Path.t()
  def write!(dir, vehicle, name, entries, frames, opts \\ []) do
    folder = Dive.path(dir, vehicle, name)
    File.mkdir_p!(folder)
    codec = Keyword.get(opts, :codec, "h264")

    {:ok, log} =
      :disk_log.open(
        name: {__MODULE__, make_ref()},
        file: String.to_charlist(Path.join(folder, Dive.part_name(1)))
      )

    started = Keyword.get(opts, :started_at, 0)

    summary =
      entries
      |> Elixir.Stream.chunk_every(1000)
      |> Enum.reduce(Summary.new(started), fn chunk, summary ->
        :ok = :disk_log.log_terms(log, chunk)
        Enum.reduce(chunk, summary, &Summary.add(&2, &1))
      end)

    :ok = :disk_log.close(log)
    video = write_video!(Dive.video_folder(folder), frames, codec, opts)

    if Keyword.get(opts, :summary, true) do
      :ok = Dive.write_summary(folder, summary, Keyword.get(opts, :closed, true), %{video: video})
    end

    folder
  end

  defp write_video!(folder, frames, codec, opts) do
    per_segment = Keyword.get(opts, :segment_frames, 1_000_000)
    info = Keyword.get(opts, :info, %{codec: codec, generation: 1})

    result =
      Enum.reduce(frames, nil, fn {at_us, key, payload}, seg ->
        seg =
          if seg == nil or (key and seg.frames >= per_segment) do
            if seg, do: close(seg)
            n = if seg, do: seg.n + 1, else: 1
            File.mkdir_p!(folder)
            {data, index} = Video.names(n, codec)

            {:ok, d} =
              :file.open(Path.join(folder, data), [:write, :raw, :binary, :delayed_write])

            {:ok, i} =
              :file.open(Path.join(folder, index), [:write, :raw, :binary, :delayed_write])

            :ok = :file.write(i, Video.header(Map.put(info, :first_seq, 0)))

            %{
              n: n,
              data: d,
              index: i,
              offset: 0,
              frames: 0,
              total: if(seg, do: seg.total, else: 0),
              bytes: if(seg, do: seg.bytes, else: 0)
            }
          else
            seg
          end

        :ok = :file.write(seg.data, payload)

        :ok =
          :file.write(
            seg.index,
            Video.record(%{
              at_us: at_us,
              capture_us: 0,
              offset: seg.offset,
              size: byte_size(payload),
              keyframe: key
            })
          )

        %{
          seg
          | offset: seg.offset + byte_size(payload),
            frames: seg.frames + 1,
            total: seg.total + 1,
            bytes: seg.bytes + byte_size(payload)
        }
      end)

    case result do
      nil ->
        nil

      seg ->
        close(seg)
        %{codec: codec, frames: seg.total, segments: seg.n, bytes: seg.bytes}
    end
  end

  defp close(seg) do
    :ok = :file.close(seg.data)
    :ok = :file.close(seg.index)
  end

  @doc """
  Telemetry entries every `period_ms` from `start_ms` for `count` entries, of a vehicle
  going down at 0.1 m/s and turning slowly (a live vehicle's shape, smaller).
  """
  @spec telemetry(integer(), pos_integer(), pos_integer()) :: [tuple()]
  def telemetry(start_ms, count, period_ms \\ 50) do
    for i <- 0..(count - 1) do
      t = i * period_ms / 1000

      {start_ms + i * period_ms, "telemetry",
       %{
         t: t,
         sent_at: start_ms + i * period_ms,
         measurement: %{depth: 0.1 * t, heading: :math.fmod(0.05 * t, 2 * :math.pi())},
         estimate: %{depth: 0.1 * t, heading: :math.fmod(0.05 * t, 2 * :math.pi())},
         thrusters: %{port: 0.1, vertical: 0.2, starboard: 0.1}
       }}
    end
  end
end
