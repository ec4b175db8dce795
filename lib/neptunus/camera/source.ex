defmodule Neptunus.Camera.Source do
  @moduledoc """
  Where a vehicle's camera images come from (`NEPTUNUS_CAMERAS=id=SOURCE`): a program that
  writes Motion JPEG to its standard output, run by `Neptunus.Vehicle.Camera`. Pure parsing.

    * `v4l2:DEVICE[@WIDTHxHEIGHT][@FPS]` — a USB/V4L2 camera through ffmpeg, taking the
      camera's own MJPEG as it is (`-input_format mjpeg -c:v copy`: no transcoding, which a
      BeagleBone could not afford). Default 640x480 at 15 fps. The OpenROV webcam does this.
    * `testsrc[@WIDTHxHEIGHT][@FPS]` — ffmpeg's test pattern, encoded to MJPEG in real time:
      a camera for demonstrations and the simulator.
    * `exec:PROGRAM [ARGS…]` — any program writing JPEG images one after the other to its
      standard output (e.g. `exec:/usr/bin/libcamera-vid -t 0 --codec mjpeg -o -`);
      arguments are separated by spaces.

  ffmpeg comes from Debian (`apt install ffmpeg`); it is looked up when the camera starts,
  and a missing program is reported by the camera, never a reason not to start the vehicle.
  """

  @type t ::
          %{
            kind: :v4l2,
            device: String.t(),
            width: pos_integer(),
            height: pos_integer(),
            fps: pos_integer()
          }
          | %{kind: :testsrc, width: pos_integer(), height: pos_integer(), fps: pos_integer()}
          | %{kind: :exec, program: String.t(), args: [String.t()]}

  @doc """
  Parses a source.

      iex> Neptunus.Camera.Source.parse("v4l2:/dev/video0@1280x720@30")
      {:ok, %{kind: :v4l2, device: "/dev/video0", width: 1280, height: 720, fps: 30}}
      iex> Neptunus.Camera.Source.parse("testsrc")
      {:ok, %{kind: :testsrc, width: 640, height: 480, fps: 15}}
      iex> Neptunus.Camera.Source.parse("v4l2:video0")
      {:error, "the device must be an absolute path such as /dev/video0"}
  """
  @spec parse(String.t()) :: {:ok, t()} | {:error, String.t()}
  def parse("v4l2:" <> rest) do
    [device | options] = String.split(rest, "@")

    with true <-
           String.starts_with?(device, "/") ||
             {:error, "the device must be an absolute path such as /dev/video0"},
         {:ok, video} <- video_options(options) do
      {:ok, Map.merge(%{kind: :v4l2, device: device}, video)}
    end
  end

  def parse("testsrc" <> rest) do
    case String.split(rest, "@") do
      ["" | options] ->
        with {:ok, video} <- video_options(options), do: {:ok, Map.put(video, :kind, :testsrc)}

      _ ->
        {:error, "testsrc takes options as testsrc@WIDTHxHEIGHT@FPS"}
    end
  end

  def parse("exec:" <> command) do
    case String.split(command, " ", trim: true) do
      [program | args] ->
        if String.starts_with?(program, "/"),
          do: {:ok, %{kind: :exec, program: program, args: args}},
          else: {:error, "exec: needs the program's absolute path, e.g. exec:/usr/bin/program"}

      [] ->
        {:error, "exec: needs a program"}
    end
  end

  def parse(_other),
    do:
      {:error,
       "a camera source: v4l2:DEVICE[@WxH][@FPS], testsrc[@WxH][@FPS] or exec:PROGRAM [ARGS]"}

  defp video_options(options) do
    Enum.reduce_while(options, {:ok, %{width: 640, height: 480, fps: 15}}, fn option,
                                                                              {:ok, acc} ->
      cond do
        match?([_, _], String.split(option, "x")) ->
          with [w, h] <- String.split(option, "x"),
               {w, ""} when w in 16..4096 <- Integer.parse(w),
               {h, ""} when h in 16..4096 <- Integer.parse(h) do
            {:cont, {:ok, %{acc | width: w, height: h}}}
          else
            _ ->
              {:halt, {:error, "a size is WIDTHxHEIGHT, each 16..4096 (got #{inspect(option)})"}}
          end

        true ->
          case Integer.parse(option) do
            {fps, ""} when fps in 1..60 -> {:cont, {:ok, %{acc | fps: fps}}}
            _ -> {:halt, {:error, "a frame rate is 1..60 (got #{inspect(option)})"}}
          end
      end
    end)
  end

  @doc """
  The program and arguments that produce the stream; `{:error, reason}` when the program is
  not installed.
  """
  @spec command(t(), (String.t() -> String.t() | nil)) ::
          {:ok, String.t(), [String.t()]} | {:error, String.t()}
  def command(source, find \\ &System.find_executable/1)

  def command(%{kind: :exec, program: program, args: args}, _find) do
    if File.regular?(program),
      do: {:ok, program, args},
      else: {:error, "camera program #{program} not found"}
  end

  def command(%{kind: kind} = source, find) when kind in [:v4l2, :testsrc] do
    case find.("ffmpeg") do
      nil -> {:error, "ffmpeg is not installed (apt install ffmpeg)"}
      ffmpeg -> {:ok, ffmpeg, ffmpeg_args(source)}
    end
  end

  defp ffmpeg_args(%{kind: :v4l2} = s) do
    ~w(-nostdin -loglevel error -f v4l2 -input_format mjpeg) ++
      ["-framerate", "#{s.fps}", "-video_size", "#{s.width}x#{s.height}", "-i", s.device] ++
      ~w(-c:v copy -f mjpeg -)
  end

  defp ffmpeg_args(%{kind: :testsrc} = s) do
    ~w(-nostdin -loglevel error -re -f lavfi -i) ++
      ["testsrc=size=#{s.width}x#{s.height}:rate=#{s.fps}"] ++ ~w(-q:v 7 -f mjpeg -)
  end
end
