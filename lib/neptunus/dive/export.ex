defmodule Neptunus.Dive.Export do
  @moduledoc """
  A dive's exports, streamed: planned first (`plan/3`: the request checked, what a first
  pass must know read), then read lazily as the client takes them (`stream/1`), so a dive of
  hours exports on a vehicle computer with little memory: no format holds more than one
  chunk, one frame or one video segment's index at a time.

    * `csv` — the telemetry, one column per numeric series (`Neptunus.Recording.csv_stream/3`);
    * `jsonl` — every entry as a JSON line, what the pages replay
      (`Neptunus.Recording.json_lines_stream/2`);
    * `ass` — the telemetry as subtitles (`Neptunus.Dive.ASS`), to put beside the video;
    * `mp4` — the video as recorded (ffmpeg copies it: nothing is re-encoded) with the
      telemetry subtitles as a track (`mov_text`, from the `.ass`), fragmented so that it is
      written as it is read; the frames keep their recorded times (from the segments'
      indexes, through a Matroska stream, `Neptunus.Dive.Matroska`), time zero its first
      frame;
    * `mcap` — for Foxglove and the robotics tools (`Neptunus.Dive.MCAP`): the telemetry on
      `/vehicle/telemetry` (JSON, a JSON schema: the wire schema's, given by the caller as
      `schemas`), the other vehicle events on `/vehicle/events`, the developer log on
      `/vehicle/log` (`foxglove.Log`), the video on `/camera` (`foxglove.CompressedVideo`,
      H.264 access units in Annex B with the SPS and PPS before each keyframe, or
      `foxglove.CompressedImage` for JPEG), every message logged at its recorded time (the
      vehicle node's wall clock), in time order, and the dive's summary as metadata.

  The MP4 runs ffmpeg under the camera port program (`priv/neptunus_camera run --linger`,
  which passes its output with flow control: at most 4 MB not yet taken; and keeps the port
  open after ffmpeg's end until the export closes it, so nothing it said is lost), and feeds it the
  Matroska stream over a Unix socket from a process of its own: the client's pace holds
  ffmpeg back, and ffmpeg's the reading.
  """

  alias Neptunus.{Dive, JSON, Recording}
  alias Neptunus.Camera.Program
  alias Neptunus.Dive.{ASS, MCAP, Matroska, Video}

  @formats ~w(csv jsonl ass mp4 mcap)

  @typedoc "What a stream reads and writes, decided on the dive's node (`plan/3`)."
  @type plan :: %{
          required(:path) => Path.t(),
          required(:format) => String.t(),
          required(:file) => String.t(),
          required(:mime) => String.t(),
          optional(atom()) => term()
        }

  @doc "The formats, as `format` takes them."
  @spec formats() :: [String.t()]
  def formats, do: @formats

  @doc """
  Plans the export of the dive at `path` (a dive folder or a legacy recording; `label` names
  the download, without extension). `options` (text, as a query string gives them):

    * `"format"` — one of #{Enum.join(@formats, ", ")} (default `csv`);
    * `"every"`, `"max"` — for `csv` and `jsonl`: every how many telemetry entries to keep
      (1..1 000 000), at most this many telemetry entries (`every` raised to keep no more);

  and, from the edge, `schemas` (`%{"telemetry" => json_schema}` for MCAP's telemetry
  channel; a bare object schema without) and `ffmpeg` (the program, default on the path).
  """
  @spec plan(Path.t(), String.t(), map()) :: {:ok, plan()} | Dive.error()
  def plan(path, label, options) do
    with {:ok, format} <- format(Map.get(options, "format", "csv")) do
      plan(format, path, label, options)
    end
  end

  defp plan(format, path, label, options) when format in ["csv", "jsonl"] do
    with {:ok, every} <- count("every", Map.get(options, "every", "1")),
         {:ok, max} <- max_rows(Map.get(options, "max")) do
      summary = path |> Dive.entries() |> Recording.scan()
      every = if max, do: max(every, ceil_div(summary.telemetry, max)), else: every

      {:ok,
       %{
         path: path,
         format: format,
         every: every,
         count: summary.entries,
         columns: summary.columns,
         file: label <> if(format == "csv", do: ".csv", else: ".jsonl"),
         mime: if(format == "csv", do: "text/csv; charset=utf-8", else: "application/x-ndjson")
       }}
    end
  end

  defp plan("ass", path, label, _options) do
    video = video_start(path)

    {:ok,
     %{
       path: path,
       format: "ass",
       zero_ms: zero_ms(path, video),
       title: label,
       file: label <> ".ass",
       mime: "text/x-ssa; charset=utf-8"
     }}
  end

  defp plan("mp4", path, label, options) do
    ffmpeg = Map.get_lazy(options, "ffmpeg", fn -> System.find_executable("ffmpeg") end)

    case video_start(path) do
      nil ->
        {:error, :conflict, "this dive has no video: export csv, jsonl, ass or mcap"}

      _video when ffmpeg == nil ->
        {:error, :failed, "ffmpeg is not installed on the vehicle's node: no MP4 export"}

      video ->
        {:ok,
         %{
           path: path,
           format: "mp4",
           video: video,
           zero_ms: div(video.zero_us, 1000),
           end_ms: video_end_ms(video),
           title: label,
           ffmpeg: ffmpeg,
           file: label <> ".mp4",
           mime: "video/mp4"
         }}
    end
  end

  defp plan("mcap", path, label, options) do
    video = video_start(path)

    {:ok,
     %{
       path: path,
       format: "mcap",
       video: video,
       title: label,
       telemetry_schema: get_in(options, ["schemas", "telemetry"]) || %{type: "object"},
       chunk_bytes: chunk_bytes(options["chunk_bytes"]),
       metadata: metadata(path, label),
       file: label <> ".mcap",
       mime: "application/octet-stream"
     }}
  end

  # the dive's video: its segments of the first segment's codec, its first frame's time and
  # what a decoder needs (nil without a readable frame)
  defp video_start(path) do
    folder = Dive.video_folder(path)

    Enum.find_value(Video.numbers(folder), fn n ->
      case Video.read(folder, n) do
        %{frames: [first | _], codec: codec, info: info} = segment ->
          numbers = for m <- Video.numbers(folder), m >= n, do: m
          {sps, pps} = first_parameter_sets(segment, codec)

          %{
            folder: folder,
            numbers: numbers,
            codec: codec,
            zero_us: first.at_us,
            width: info["width"],
            height: info["height"],
            sps: sps,
            pps: pps
          }

        _ ->
          nil
      end
    end)
  end

  defp first_parameter_sets(segment, "h264") do
    segment
    |> Video.payloads()
    |> Enum.take(1)
    |> case do
      [{_, _, payload}] -> Matroska.parameter_sets(payload)
      [] -> {nil, []}
    end
  end

  defp first_parameter_sets(_segment, _codec), do: {nil, []}

  defp zero_ms(_path, %{zero_us: us}), do: div(us, 1000)

  defp zero_ms(path, nil) do
    case path |> Dive.entries() |> Enum.take(1) do
      [{at, _, _}] -> at
      [] -> 0
    end
  end

  defp metadata(path, label) do
    info =
      case Dive.info(
             Path.dirname(Path.dirname(path)),
             Path.basename(Path.dirname(path)),
             Path.basename(path)
           ) do
        nil -> %{}
        info -> info
      end

    fields =
      %{
        "dive" => label,
        "started_at" => info[:started_at],
        "ended_at" => info[:ended_at],
        "duration_ms" => info[:duration_ms],
        "max_depth_m" => info[:max_depth],
        "pilots" => Enum.join(info[:pilots] || [], ", "),
        "stops" => info[:stops],
        "snapshots" => info[:snapshots],
        "title" => info[:title],
        "notes" => info[:notes]
      }
      |> Enum.reject(fn {_k, v} -> v in [nil, ""] end)
      |> Map.new(fn {k, v} -> {k, to_string(v)} end)

    [{"neptunus.dive", fields}]
  end

  @doc "The export of `plan`, a lazy enumerable of iodata."
  @spec stream(plan()) :: Enumerable.t()
  def stream(%{format: "csv"} = plan) do
    entries = plan.path |> Dive.entries() |> Stream.take(plan.count)
    Recording.csv_stream(entries, plan.columns, plan.every)
  end

  def stream(%{format: "jsonl"} = plan) do
    entries = plan.path |> Dive.entries() |> Stream.take(plan.count)
    Recording.json_lines_stream(entries, plan.every)
  end

  def stream(%{format: "ass"} = plan) do
    cues = plan.path |> Dive.entries() |> ASS.cues(plan.zero_ms) |> until(plan[:end_ms])
    Stream.concat([ASS.header(plan.title)], Stream.map(cues, &ASS.dialogue/1))
  end

  def stream(%{format: "mcap"} = plan), do: mcap(plan)
  def stream(%{format: "mp4"} = plan), do: mp4(plan)

  # an MP4's cues end with its video
  defp until(cues, nil), do: cues

  defp until(cues, end_ms) do
    cues
    |> Stream.take_while(fn {start, _end, _text} -> start < end_ms end)
    |> Stream.map(fn {start, stop, text} -> {start, min(stop, end_ms), text} end)
  end

  # the video's end, relative to its first frame: its last frame's time plus one frame
  defp video_end_ms(video) do
    last = video.folder |> Video.read(List.last(video.numbers))

    case Enum.take(last.frames, -2) do
      [a, b] -> div(b.at_us - video.zero_us + (b.at_us - a.at_us) + 500, 1000)
      [b] -> div(b.at_us - video.zero_us + 500, 1000)
      [] -> nil
    end
  end

  # MCAP

  @telemetry_ch 1
  @events_ch 2
  @log_ch 3
  @camera_ch 4

  defp mcap(plan) do
    Stream.resource(
      fn -> :start end,
      fn
        :start ->
          {state, head} = MCAP.new(mcap_options(plan))
          {[head], {state, pull(mcap_items(plan))}}

        {state, items} ->
          # a batch of items at a time: the continuation of the merged stream
          case take(items, 64) do
            {[], _rest} ->
              {[MCAP.finish(state)], :done}

            {batch, rest} ->
              {state, out} =
                Enum.reduce(batch, {state, []}, fn item, {state, out} ->
                  {ch, t, data} = mcap_message(item, plan)
                  {state, bytes} = MCAP.message(state, ch, t, data)
                  {state, [out, bytes]}
                end)

              {[out], {state, rest}}
          end

        :done ->
          {:halt, :done}
      end,
      fn
        {_state, cursor} -> close(cursor)
        _ -> :ok
      end
    )
  end

  defp mcap_options(plan) do
    schemas = [
      %{
        id: 1,
        name: "neptunus.Telemetry",
        encoding: "jsonschema",
        data: JSON.encode!(plan.telemetry_schema)
      },
      %{
        id: 2,
        name: "neptunus.VehicleEvent",
        encoding: "jsonschema",
        data: JSON.encode!(event_schema())
      },
      %{id: 3, name: "foxglove.Log", encoding: "jsonschema", data: JSON.encode!(log_schema())}
    ]

    channels = [
      %{
        id: @telemetry_ch,
        schema_id: 1,
        topic: "/vehicle/telemetry",
        message_encoding: "json",
        metadata: %{}
      },
      %{
        id: @events_ch,
        schema_id: 2,
        topic: "/vehicle/events",
        message_encoding: "json",
        metadata: %{}
      },
      %{id: @log_ch, schema_id: 3, topic: "/vehicle/log", message_encoding: "json", metadata: %{}}
    ]

    {schemas, channels} =
      case plan.video do
        nil ->
          {schemas, channels}

        video ->
          {name, schema} = image_schema(video.codec)

          {schemas ++ [%{id: 4, name: name, encoding: "jsonschema", data: JSON.encode!(schema)}],
           channels ++
             [
               %{
                 id: @camera_ch,
                 schema_id: 4,
                 topic: "/camera",
                 message_encoding: "json",
                 metadata: %{"codec" => video.codec}
               }
             ]}
      end

    [
      schemas: schemas,
      channels: channels,
      metadata: plan.metadata,
      profile: "",
      library: "neptunus",
      chunk_bytes: plan.chunk_bytes
    ]
  end

  # entries and frames, merged by time
  defp mcap_items(plan) do
    entries = Dive.entries(plan.path)

    case plan.video do
      nil ->
        entries

      video ->
        frames = Video.frames(video.folder, video.numbers)
        merge(entries, frames, fn {at, _, _} -> at * 1000 end, fn {_, f, _} -> f.at_us end)
    end
  end

  defp mcap_message({at, "telemetry", payload}, _plan),
    do: {@telemetry_ch, at * 1_000_000, JSON.encode!(payload)}

  defp mcap_message({at, "log", payload}, _plan) do
    level =
      case Map.get(payload, :level) do
        "error" -> 4
        "warning" -> 3
        _ -> 2
      end

    message = %{
      timestamp: time(at * 1_000_000),
      level: level,
      message: to_string(Map.get(payload, :message, "")),
      name: to_string(Map.get(payload, :category, "")),
      file: "",
      line: 0
    }

    {@log_ch, at * 1_000_000, JSON.encode!(message)}
  end

  defp mcap_message({at, event, payload}, _plan) when is_binary(event),
    do: {@events_ch, at * 1_000_000, JSON.encode!(%{event: event, payload: payload})}

  defp mcap_message({segment, frame, payload}, _plan) do
    t = frame.at_us * 1000
    format = if segment.codec == "h264", do: "h264", else: "jpeg"

    data = [
      ~s({"timestamp":),
      JSON.encode!(time(t)),
      ~s(,"frame_id":"camera","format":"),
      format,
      ~s(","data":"),
      Base.encode64(payload),
      ~s("})
    ]

    {@camera_ch, t, data}
  end

  defp time(ns), do: %{sec: div(ns, 1_000_000_000), nsec: rem(ns, 1_000_000_000)}

  defp event_schema do
    %{
      title: "neptunus.VehicleEvent",
      description: "An event the vehicle published (docs/API.md): stopped, helm, link, …",
      type: "object",
      properties: %{
        event: %{type: "string", description: "the event's name"},
        payload: %{type: "object", description: "as broadcast on vehicle:<id>"}
      }
    }
  end

  defp time_schema do
    %{
      type: "object",
      title: "time",
      properties: %{
        sec: %{type: "integer", minimum: 0},
        nsec: %{type: "integer", minimum: 0, maximum: 999_999_999}
      }
    }
  end

  defp log_schema do
    %{
      title: "foxglove.Log",
      description: "A log message",
      type: "object",
      properties: %{
        timestamp: time_schema(),
        level: %{type: "integer", description: "1 debug, 2 info, 3 warning, 4 error, 5 fatal"},
        message: %{type: "string"},
        name: %{type: "string", description: "the developer logger's category"},
        file: %{type: "string"},
        line: %{type: "integer", minimum: 0}
      }
    }
  end

  defp image_schema(codec) do
    name = if codec == "h264", do: "foxglove.CompressedVideo", else: "foxglove.CompressedImage"

    {name,
     %{
       title: name,
       type: "object",
       properties: %{
         timestamp: time_schema(),
         frame_id: %{type: "string"},
         data: %{type: "string", contentEncoding: "base64"},
         format: %{type: "string"}
       }
     }}
  end

  # MP4

  defp mp4(plan) do
    Stream.resource(
      fn -> start_mp4(plan) end,
      &next_mp4/1,
      &stop_mp4/1
    )
  end

  defp start_mp4(plan) do
    tmp = Path.join(System.tmp_dir!(), "neptunus-export-#{System.unique_integer([:positive])}")
    File.mkdir_p!(tmp)
    File.chmod!(tmp, 0o700)

    try do
      subs = Path.join(tmp, "telemetry.ass")
      File.write!(subs, Enum.to_list(stream(%{plan | format: "ass"})))
      sock = Path.join(tmp, "video.sock")

      {:ok, listen} =
        :gen_tcp.listen(0, [:binary, active: false, ifaddr: {:local, String.to_charlist(sock)}])

      feeder = spawn_feeder(listen, plan.video)
      port = open_ffmpeg(plan, sock, subs)
      %{port: port, feeder: feeder, listen: listen, tmp: tmp, errors: [], bytes: 0}
    rescue
      error ->
        File.rm_rf(tmp)
        reraise error, __STACKTRACE__
    end
  end

  defp next_mp4(%{port: port} = s) do
    receive do
      {^port, {:data, <<?d, bytes::binary>>}} ->
        Program.ack(port, byte_size(bytes))
        {[bytes], %{s | bytes: s.bytes + byte_size(bytes)}}

      {^port, {:data, <<?e, line::binary>>}} ->
        next_mp4(%{s | errors: Enum.take([line | s.errors], 5)})

      # ffmpeg ended (the port program says its code before it exits, as the VM may see the
      # port close without an exit status)
      {^port, {:data, <<?x, 0>>}} ->
        {:halt, s}

      {^port, {:data, <<?x, status>>}} ->
        raise ErlangError,
          original: {:ffmpeg, status, Enum.join(Enum.reverse(s.errors), "; ")}

      {^port, {:data, _}} ->
        next_mp4(s)

      {^port, {:exit_status, 0}} ->
        {:halt, %{s | port: nil}}

      {^port, {:exit_status, status}} ->
        raise ErlangError,
          original: {:ffmpeg, status, Enum.join(Enum.reverse(s.errors), "; ")}

      {:feeder_failed, reason} ->
        raise ErlangError, original: {:video, reason}
    after
      60_000 ->
        # what each side was doing, for the report: ffmpeg's last words, whether the feeder
        # still feeds it (and where it waits)
        feeder = Process.info(s.feeder, [:status, :current_function])

        raise ErlangError,
          original:
            {:ffmpeg, :timeout,
             %{errors: Enum.reverse(s.errors), output_bytes: s.bytes, feeder: feeder}}
    end
  end

  defp next_mp4(s), do: {:halt, s}

  defp stop_mp4(s) do
    if s.port, do: Program.close(s.port)

    Process.exit(s.feeder, :kill)
    :gen_tcp.close(s.listen)
    File.rm_rf(s.tmp)
  end

  defp open_ffmpeg(plan, sock, subs) do
    # --linger: the program keeps its end of the port open after ffmpeg's end until we close
    # it, so an acknowledgement written meanwhile never fails (EPIPE would close the port and
    # drop what the program said last: output, and the end itself)
    args =
      ["run", "--linger", "--", plan.ffmpeg] ++
        ~w(-nostdin -hide_banner -loglevel error -f matroska -i) ++
        ["unix:" <> sock] ++
        ["-i", subs] ++
        ~w(-map 0:v -map 1:s -c:v copy -c:s mov_text -metadata:s:s:0 language=eng) ++
        ["-metadata", "title=#{plan.title}"] ++
        ~w(-movflags frag_keyframe+empty_moov+default_base_moof -f mp4 pipe:1)

    port = Program.open(args)

    # the port's end is read from 'x', never taken as an exit signal by the caller (an API
    # request, a mix task)
    Process.unlink(port)
    port
  end

  # feeds ffmpeg the Matroska stream over the socket, at ffmpeg's pace
  defp spawn_feeder(listen, video) do
    owner = self()

    spawn(fn ->
      ref = Process.monitor(owner)

      with {:ok, socket} <- :gen_tcp.accept(listen, 30_000),
           :ok <- feed(socket, video) do
        :gen_tcp.close(socket)
      else
        {:error, reason} -> send(owner, {:feeder_failed, reason})
      end

      Process.demonitor(ref)
    end)
  end

  defp feed(socket, video) do
    track = %{
      codec: video.codec,
      width: video.width,
      height: video.height,
      sps: video.sps,
      pps: video.pps
    }

    frames =
      video.folder
      |> Video.frames(video.numbers)
      |> Stream.filter(fn {segment, _, _} -> segment.codec == video.codec end)
      |> Stream.map(fn {_, f, payload} -> {f.at_us, f.keyframe, payload} end)

    [Matroska.header(track)]
    |> Stream.concat(Matroska.blocks(frames, video.codec, video.zero_us))
    |> Stream.chunk_every(32)
    |> Enum.reduce_while(:ok, fn chunk, :ok ->
      case :gen_tcp.send(socket, chunk) do
        :ok -> {:cont, :ok}
        # ffmpeg stopped reading (it ended, or failed: its exit says why)
        {:error, :closed} -> {:halt, :ok}
        {:error, :epipe} -> {:halt, :ok}
        {:error, reason} -> {:halt, {:error, reason}}
      end
    end)
  end

  # Merging two time-ordered streams lazily

  @doc """
  Merges two enumerables ordered by `key_a` and `key_b` (the same clock), lazily, into one
  ordered stream (`a` first at equal keys).

      iex> Neptunus.Dive.Export.merge([1, 4, 5], [2, 3, 6], & &1, & &1) |> Enum.to_list()
      [1, 2, 3, 4, 5, 6]
  """
  @spec merge(Enumerable.t(), Enumerable.t(), (term() -> number()), (term() -> number())) ::
          Enumerable.t()
  def merge(a, b, key_a, key_b) do
    Stream.resource(
      fn -> {pull(a), pull(b)} end,
      fn
        {:done, :done} = acc ->
          {:halt, acc}

        {{x, _} = left, :done} ->
          {[x], {advance(left), :done}}

        {:done, {y, _} = right} ->
          {[y], {:done, advance(right)}}

        {{x, _} = left, {y, _} = right} ->
          if key_a.(x) <= key_b.(y),
            do: {[x], {advance(left), right}},
            else: {[y], {left, advance(right)}}
      end,
      fn {left, right} ->
        close(left)
        close(right)
      end
    )
  end

  # A cursor over an enumerable: `{item, continuation}` or `:done`; the enumeration is
  # suspended between items (its source stays open until the cursor is closed).
  defp pull(enum), do: step(Enumerable.reduce(enum, {:cont, nil}, fn x, _ -> {:suspend, x} end))

  defp advance({_x, continuation}), do: step(continuation.({:cont, nil}))

  defp step({:suspended, x, continuation}), do: {x, continuation}
  defp step({:done, _}), do: :done
  defp step({:halted, _}), do: :done

  defp close({_x, continuation}) do
    _ = continuation.({:halt, nil})
    :ok
  end

  defp close(_done), do: :ok

  # up to n items of a cursor
  defp take(cursor, n), do: take(cursor, n, [])
  defp take(:done, _n, acc), do: {Enum.reverse(acc), :done}
  defp take(cursor, 0, acc), do: {Enum.reverse(acc), cursor}
  defp take({x, _} = cursor, n, acc), do: take(advance(cursor), n - 1, [x | acc])

  # Options

  defp format(format) when format in @formats, do: {:ok, format}

  defp format(other),
    do:
      {:error, :invalid,
       "format must be one of #{Enum.join(@formats, ", ")}, got #{inspect(other)}"}

  defp max_rows(nil), do: {:ok, nil}
  defp max_rows(text), do: count("max", text)

  defp count(name, text) do
    case is_binary(text) && Integer.parse(text) do
      {n, ""} when n in 1..1_000_000 ->
        {:ok, n}

      _ ->
        {:error, :invalid, "#{name} must be an integer in 1..1000000, got #{inspect(text)}"}
    end
  end

  # MCAP chunks of 1 MiB, or (tests) smaller
  defp chunk_bytes(n) when is_integer(n) and n >= 1024, do: n
  defp chunk_bytes(_), do: 1_048_576

  defp ceil_div(a, b), do: max(1, div(a + b - 1, b))
end
