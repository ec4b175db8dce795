defmodule Neptunus.Camera.Source do
  @moduledoc """
  Where a vehicle's camera pictures come from (`NEPTUNUS_CAMERAS=id=SOURCE`), and the program
  that produces them, run by `Neptunus.Vehicle.Camera` through the camera port program
  (`priv/neptunus_camera`). Pure.

    * `v4l2:DEVICE[@h264|@mjpeg][@WIDTHxHEIGHT][@FPS]` — a USB/V4L2 camera through ffmpeg,
      its own codec passed through (`-c:v copy`), never re-encoded (a BeagleBone could not
      afford it): H.264 if the camera offers it, else MJPEG, decided by probing the device
      (`Neptunus.Camera.V4L2`) unless `@h264` or `@mjpeg` forces one. Default 640x480 at
      15 fps.
    * `rtsp://…` (or `rtsps://…`) — an IP camera's H.264 passed through by ffmpeg (over TCP).
      The URL is taken whole (it may hold `user:password@`, which logs never show).
    * `sim[@h264|@mjpeg][@WIDTHxHEIGHT][@FPS][@bottom=METRES]` — the simulator's view: the
      camera port program renders it from the vehicle's true pose (published by its
      simulator) and ffmpeg encodes it (H.264 by default). Default 640x360 at 30 fps, the
      seabed 10 m deep; the width at least 384 (the render-time code in the corner is 384
      pixels wide), width and height even. The default camera of `simulated` and `sitl`
      vehicles.
    * `testsrc[@h264|@mjpeg][@WIDTHxHEIGHT][@FPS]` — ffmpeg's test pattern, encoded in real
      time (MJPEG by default). Default 640x480 at 15 fps.
    * `exec:PROGRAM [ARGS…]` — any program writing JPEG images one after the other to its
      standard output (e.g. `exec:/usr/bin/libcamera-vid -t 0 --codec mjpeg -o -`);
      `exec@h264:PROGRAM [ARGS…]` one writing H.264 in Annex B (start codes, e.g.
      `libcamera-vid --codec h264 --inline -o -`). Arguments are separated by spaces.

  H.264 from ffmpeg comes as FLV (each picture a tag of known length, so a picture is
  complete the moment its last byte arrives); from `exec@h264` as Annex B, where a picture
  is known complete only when the next one starts (one frame later).

  ffmpeg comes from Debian (`make setup` installs it); it is looked up when the camera
  starts, and a missing program is reported by the camera, never a reason not to start the
  vehicle.
  """

  @type codec :: :h264 | :mjpeg

  @type t ::
          %{
            kind: :v4l2,
            device: String.t(),
            codec: codec() | :auto,
            width: pos_integer(),
            height: pos_integer(),
            fps: pos_integer()
          }
          | %{kind: :rtsp, url: String.t()}
          | %{
              kind: :sim,
              codec: codec(),
              width: pos_integer(),
              height: pos_integer(),
              fps: pos_integer(),
              bottom: float()
            }
          | %{
              kind: :testsrc,
              codec: codec(),
              width: pos_integer(),
              height: pos_integer(),
              fps: pos_integer()
            }
          | %{kind: :exec, codec: codec(), program: String.t(), args: [String.t()]}

  @typedoc """
  How the program's output is cut into pictures: `:flv` (H.264 in FLV tags, from ffmpeg),
  `:annexb` (H.264 with start codes) or `:mjpeg` (JPEG images one after the other).
  """
  @type format :: :flv | :annexb | :mjpeg

  @typedoc """
  The programs a command needs: `ffmpeg` (nil: not installed) and `camera`, the camera port
  program (`priv/neptunus_camera`) every source runs through.
  """
  @type tools :: %{ffmpeg: String.t() | nil, camera: String.t()}

  @typedoc "What to run: the camera port program and its arguments, and the output's format."
  @type command :: %{executable: String.t(), args: [String.t()], format: format()}

  @usage "a camera source: v4l2:DEVICE[@h264|@mjpeg][@WxH][@FPS], rtsp://…, " <>
           "sim[@h264|@mjpeg][@WxH][@FPS][@bottom=M], testsrc[@h264|@mjpeg][@WxH][@FPS], " <>
           "exec:PROGRAM [ARGS] or exec@h264:PROGRAM [ARGS]"

  @doc """
  Parses a source.

      iex> Neptunus.Camera.Source.parse("v4l2:/dev/video0@1280x720@30")
      {:ok, %{kind: :v4l2, device: "/dev/video0", codec: :auto, width: 1280, height: 720, fps: 30}}
      iex> Neptunus.Camera.Source.parse("testsrc")
      {:ok, %{kind: :testsrc, codec: :mjpeg, width: 640, height: 480, fps: 15}}
      iex> Neptunus.Camera.Source.parse("sim")
      {:ok, %{kind: :sim, codec: :h264, width: 640, height: 360, fps: 30, bottom: 10.0}}
      iex> Neptunus.Camera.Source.parse("v4l2:video0")
      {:error, "the device must be an absolute path such as /dev/video0"}
  """
  @spec parse(String.t()) :: {:ok, t()} | {:error, String.t()}
  def parse("v4l2:" <> rest) do
    [device | options] = String.split(rest, "@")

    with true <-
           String.starts_with?(device, "/") ||
             {:error, "the device must be an absolute path such as /dev/video0"},
         {:ok, video} <- video_options(options, %{codec: :auto, width: 640, height: 480, fps: 15}) do
      {:ok, Map.merge(%{kind: :v4l2, device: device}, video)}
    end
  end

  def parse("rtsp://" <> _ = url), do: rtsp(url)
  def parse("rtsps://" <> _ = url), do: rtsp(url)

  def parse("sim" <> rest) do
    defaults = %{codec: :h264, width: 640, height: 360, fps: 30, bottom: 10.0}

    with {:ok, options} <- options_of("sim", rest),
         {:ok, video} <- video_options(options, defaults),
         :ok <- sim_size(video) do
      {:ok, Map.put(video, :kind, :sim)}
    end
  end

  def parse("testsrc" <> rest) do
    with {:ok, options} <- options_of("testsrc", rest),
         {:ok, video} <-
           video_options(options, %{codec: :mjpeg, width: 640, height: 480, fps: 15}) do
      {:ok, Map.put(video, :kind, :testsrc)}
    end
  end

  def parse("exec:" <> command), do: exec(:mjpeg, command)
  def parse("exec@h264:" <> command), do: exec(:h264, command)
  def parse("exec@mjpeg:" <> command), do: exec(:mjpeg, command)
  def parse(_other), do: {:error, @usage}

  defp options_of(name, rest) do
    case String.split(rest, "@") do
      ["" | options] -> {:ok, options}
      _ -> {:error, "#{name} takes options as #{name}@OPTION@…, e.g. #{name}@640x360@30"}
    end
  end

  defp rtsp(url) do
    case URI.parse(url) do
      %URI{host: host} when is_binary(host) and host != "" ->
        {:ok, %{kind: :rtsp, url: url}}

      _ ->
        {:error, "an RTSP source is a URL such as rtsp://192.168.2.10:554/stream"}
    end
  end

  defp exec(codec, command) do
    case String.split(command, " ", trim: true) do
      [program | args] ->
        if String.starts_with?(program, "/"),
          do: {:ok, %{kind: :exec, codec: codec, program: program, args: args}},
          else: {:error, "exec: needs the program's absolute path, e.g. exec:/usr/bin/program"}

      [] ->
        {:error, "exec: needs a program"}
    end
  end

  defp sim_size(%{width: w, height: h}) do
    cond do
      w < 384 -> {:error, "the sim camera is at least 384 pixels wide (its time code), got #{w}"}
      h < 64 -> {:error, "the sim camera is at least 64 pixels high, got #{h}"}
      rem(w, 2) + rem(h, 2) != 0 -> {:error, "the sim camera's size is even, got #{w}x#{h}"}
      true -> :ok
    end
  end

  defp video_options(options, defaults) do
    Enum.reduce_while(options, {:ok, defaults}, fn option, {:ok, acc} ->
      case video_option(option, acc) do
        {:ok, acc} -> {:cont, {:ok, acc}}
        {:error, _} = error -> {:halt, error}
      end
    end)
  end

  defp video_option(codec, acc) when codec in ["h264", "mjpeg"],
    do: {:ok, %{acc | codec: String.to_existing_atom(codec)}}

  defp video_option("bottom=" <> metres, %{bottom: _} = acc) do
    case Float.parse(metres) do
      {m, ""} when m >= 1.0 and m <= 1000.0 -> {:ok, %{acc | bottom: m}}
      _ -> {:error, "the sim camera's bottom is a depth in m, 1..1000 (got #{inspect(metres)})"}
    end
  end

  defp video_option(option, acc) do
    cond do
      String.contains?(option, "x") ->
        with [w, h] <- String.split(option, "x"),
             {w, ""} when w in 16..4096 <- Integer.parse(w),
             {h, ""} when h in 16..4096 <- Integer.parse(h) do
          {:ok, %{acc | width: w, height: h}}
        else
          _ -> {:error, "a size is WIDTHxHEIGHT, each 16..4096 (got #{inspect(option)})"}
        end

      match?({_, ""}, Integer.parse(option)) ->
        case Integer.parse(option) do
          {fps, ""} when fps in 1..60 -> {:ok, %{acc | fps: fps}}
          _ -> {:error, "a frame rate is 1..60 (got #{inspect(option)})"}
        end

      true ->
        {:error, "unknown camera option #{inspect(option)}: h264, mjpeg, WxH or FPS"}
    end
  end

  @doc """
  The source as logs and pages may show it: an RTSP URL without its password.

      iex> Neptunus.Camera.Source.describe(%{kind: :rtsp, url: "rtsp://admin:secret@10.0.0.5/s"})
      "rtsp://admin@10.0.0.5/s"
      iex> Neptunus.Camera.Source.describe(%{kind: :sim, codec: :h264, width: 640, height: 360, fps: 30, bottom: 10.0})
      "sim@h264@640x360@30"
  """
  @spec describe(t()) :: String.t()
  def describe(%{kind: :rtsp, url: url}) do
    uri = URI.parse(url)

    case uri.userinfo do
      nil -> url
      info -> URI.to_string(%{uri | userinfo: info |> String.split(":") |> hd()})
    end
  end

  def describe(%{kind: :exec, codec: codec, program: program}),
    do: "exec#{if codec == :h264, do: "@h264", else: ""}:#{program}"

  def describe(%{kind: kind} = s) do
    codec = if s.codec == :auto, do: "", else: "@#{s.codec}"

    "#{kind}#{if kind == :v4l2, do: ":" <> s.device, else: ""}#{codec}@#{s.width}x#{s.height}@#{s.fps}"
  end

  @doc """
  `text` (a program's error line) without the source's password, if it has one.

      iex> source = %{kind: :rtsp, url: "rtsp://admin:s3cret@10.0.0.5/s"}
      iex> Neptunus.Camera.Source.redact("rtsp://admin:s3cret@10.0.0.5/s: Connection refused", source)
      "rtsp://admin:***@10.0.0.5/s: Connection refused"
  """
  @spec redact(String.t(), t() | nil) :: String.t()
  def redact(text, %{kind: :rtsp, url: url}) do
    case URI.parse(url).userinfo do
      nil ->
        text

      info ->
        case String.split(info, ":", parts: 2) do
          [_user, ""] -> text
          [user, password] -> String.replace(text, user <> ":" <> password, user <> ":***")
          [_user] -> text
        end
    end
  end

  def redact(text, _source), do: text

  @doc """
  The codec the source sends (`:auto`: a V4L2 camera not probed yet, see
  `Neptunus.Camera.V4L2`).
  """
  @spec codec(t()) :: codec() | :auto
  def codec(%{kind: :rtsp}), do: :h264
  def codec(%{codec: codec}), do: codec

  @doc """
  The frame rate the source is configured for, nil when the source alone knows it (RTSP,
  exec).
  """
  @spec fps(t()) :: pos_integer() | nil
  def fps(%{fps: fps}), do: fps
  def fps(_source), do: nil

  @doc """
  What to run for `source`: `{:ok, command}`, or `{:error, reason}` when a program is not
  installed or a V4L2 camera's codec is not known yet (probe it first, `probe_command/2`).
  Every source runs through the camera port program: `run -- PROGRAM ARGS` (it passes the
  program's output on and its error output as lines), or `sim …` for the simulator's view.
  """
  @spec command(t(), tools()) :: {:ok, command()} | {:error, String.t()}
  def command(%{kind: :exec} = s, tools) do
    if File.regular?(s.program),
      do: {:ok, run(tools, s.program, s.args, format(s))},
      else: {:error, "camera program #{s.program} not found"}
  end

  def command(%{kind: :v4l2, codec: :auto}, _tools),
    do: {:error, "the camera's codec is not known yet: probe the device first"}

  def command(_source, %{ffmpeg: nil}), do: {:error, ffmpeg_missing()}

  def command(%{kind: :sim} = s, %{ffmpeg: ffmpeg, camera: camera}) do
    args =
      ["sim", "#{s.width}", "#{s.height}", "#{s.fps}", float(s.bottom), "--", ffmpeg] ++
        ~w(-nostdin -hide_banner -loglevel error -f rawvideo -pix_fmt yuv420p) ++
        ["-video_size", "#{s.width}x#{s.height}", "-framerate", "#{s.fps}", "-i", "pipe:0"] ++
        encode(s.codec, s.fps) ++ ["pipe:1"]

    {:ok, %{executable: camera, args: args, format: format(s)}}
  end

  def command(%{kind: :testsrc} = s, %{ffmpeg: ffmpeg} = tools) do
    args =
      ~w(-nostdin -hide_banner -loglevel error -re -f lavfi -i) ++
        ["testsrc=size=#{s.width}x#{s.height}:rate=#{s.fps}"] ++ encode(s.codec, s.fps) ++ ["-"]

    {:ok, run(tools, ffmpeg, args, format(s))}
  end

  def command(%{kind: :v4l2} = s, %{ffmpeg: ffmpeg} = tools) do
    args =
      ~w(-nostdin -hide_banner -loglevel error -fflags nobuffer -f v4l2 -input_format) ++
        ["#{s.codec}", "-framerate", "#{s.fps}", "-video_size", "#{s.width}x#{s.height}"] ++
        ["-i", s.device, "-c:v", "copy"] ++ container(s.codec) ++ ["-"]

    {:ok, run(tools, ffmpeg, args, format(s))}
  end

  def command(%{kind: :rtsp} = s, %{ffmpeg: ffmpeg} = tools) do
    # -timeout: a server that stops answering ends ffmpeg (µs) rather than hanging it
    args =
      ~w(-nostdin -hide_banner -loglevel error -fflags nobuffer -rtsp_transport tcp) ++
        ["-timeout", "5000000", "-i", s.url] ++
        ~w(-map 0:v:0 -c:v copy -an) ++ container(:h264) ++ ["-"]

    {:ok, run(tools, ffmpeg, args, :flv)}
  end

  @doc """
  What lists a V4L2 camera's formats (`ffmpeg -f v4l2 -list_formats all`, whose answer is
  its error output, see `Neptunus.Camera.V4L2.decide/2`).
  """
  @spec probe_command(t(), tools()) :: {:ok, command()} | {:error, String.t()}
  def probe_command(%{kind: :v4l2}, %{ffmpeg: nil}), do: {:error, ffmpeg_missing()}

  def probe_command(%{kind: :v4l2, device: device}, %{ffmpeg: ffmpeg} = tools) do
    args = ~w(-nostdin -hide_banner -loglevel info -f v4l2 -list_formats all -i) ++ [device]
    {:ok, run(tools, ffmpeg, args, :mjpeg)}
  end

  @doc "How the source's output is cut into pictures (see `t:format/0`)."
  @spec format(t()) :: format()
  def format(%{kind: :exec, codec: :h264}), do: :annexb
  def format(source), do: if(codec(source) == :h264, do: :flv, else: :mjpeg)

  defp run(%{camera: camera}, program, args, format),
    do: %{executable: camera, args: ["run", "--", program | args], format: format}

  # H.264 for a browser: 4:2:0, constrained baseline (no B-frames: every picture goes out as
  # soon as it is encoded), a keyframe every second whatever the picture does.
  defp encode(:h264, fps) do
    ~w(-c:v libx264 -preset ultrafast -tune zerolatency -profile:v baseline -pix_fmt yuv420p) ++
      ["-g", "#{fps}", "-keyint_min", "#{fps}", "-sc_threshold", "0", "-bf", "0"] ++
      container(:h264)
  end

  defp encode(:mjpeg, _fps), do: ~w(-c:v mjpeg -pix_fmt yuvj420p -q:v 7) ++ container(:mjpeg)

  defp container(:h264), do: ~w(-f flv -flvflags no_duration_filesize -flush_packets 1)
  defp container(:mjpeg), do: ~w(-f mjpeg -flush_packets 1)

  defp float(x), do: :erlang.float_to_binary(x * 1.0, decimals: 2)

  defp ffmpeg_missing, do: "ffmpeg is not installed (make setup, or apt install ffmpeg)"
end
