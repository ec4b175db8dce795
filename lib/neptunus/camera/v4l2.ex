defmodule Neptunus.Camera.V4L2 do
  @moduledoc """
  Which codec to take from a V4L2 camera (pure): the camera's own H.264 if it offers it
  (most ROV cameras do: less bandwidth and a smoother picture than MJPEG at the same
  quality), else its MJPEG, never a raw format (it would have to be encoded on the vehicle,
  which a BeagleBone cannot afford). `@h264` or `@mjpeg` in the source forces one, if the
  camera offers it.

  The formats are what `ffmpeg -f v4l2 -list_formats all -i DEVICE` prints on its error
  output (`Neptunus.Camera.Source.probe_command/2`), one line per format:

      [video4linux2,v4l2 @ 0x5581e0c1c0c0] Raw       :     yuyv422 :           YUYV 4:2:2 : 640x480 1280x720
      [video4linux2,v4l2 @ 0x5581e0c1c0c0] Compressed:       mjpeg :          Motion-JPEG : 640x480 1280x720
      [video4linux2,v4l2 @ 0x5581e0c1c0c0] Compressed:        h264 :                H.264 : 640x480 1280x720

  The sizes listed are discrete (`WxH …`) or a range (`{min-max, step}x{min-max, step}`); a
  size the camera does not list is reported, not guessed around.
  """

  @typedoc "A format the camera offers: ffmpeg's codec name, compressed or raw, its sizes."
  @type format :: %{
          codec: String.t(),
          compressed: boolean(),
          sizes: [{pos_integer(), pos_integer()}] | :range
        }

  @doc """
  The formats listed in ffmpeg's output (`lines`, without their newline).

      iex> Neptunus.Camera.V4L2.formats([
      ...>   "[video4linux2,v4l2 @ 0x55] Compressed:       mjpeg :          Motion-JPEG : 640x480 1280x720",
      ...>   "/dev/video0: Immediate exit requested"])
      [%{codec: "mjpeg", compressed: true, sizes: [{640, 480}, {1280, 720}]}]
  """
  @spec formats([String.t()]) :: [format()]
  def formats(lines) do
    Enum.flat_map(lines, fn line ->
      case Regex.run(~r/\] (Compressed|Raw)\s*:\s*(\S+)\s*:[^:]*:(.*)$/, line) do
        [_, kind, codec, sizes] ->
          [%{codec: codec, compressed: kind == "Compressed", sizes: sizes(sizes)}]

        nil ->
          []
      end
    end)
  end

  defp sizes(text) do
    if String.contains?(text, "{") do
      :range
    else
      for size <- String.split(text),
          [w, h] <- [String.split(size, "x")],
          {w, ""} <- [Integer.parse(w)],
          {h, ""} <- [Integer.parse(h)],
          do: {w, h}
    end
  end

  @doc """
  Decides the codec for `source` (a `v4l2` source) from ffmpeg's `lines`: `{:ok, codec}`, or
  `{:error, reason}` saying what the camera offers instead.

      iex> lines = ["[v4l2 @ 0x1] Raw       :     yuyv422 :  YUYV 4:2:2 : 640x480",
      ...>          "[v4l2 @ 0x1] Compressed:        h264 :        H.264 : 640x480",
      ...>          "[v4l2 @ 0x1] Compressed:       mjpeg :  Motion-JPEG : 640x480"]
      iex> source = %{kind: :v4l2, device: "/dev/video0", codec: :auto, width: 640, height: 480, fps: 15}
      iex> Neptunus.Camera.V4L2.decide(lines, source)
      {:ok, :h264}
      iex> Neptunus.Camera.V4L2.decide(lines, %{source | codec: :mjpeg})
      {:ok, :mjpeg}
      iex> Neptunus.Camera.V4L2.decide(Enum.take(lines, 1), source)
      {:error, "/dev/video0 offers neither H.264 nor MJPEG (only yuyv422), and video is not re-encoded on the vehicle"}
  """
  @spec decide([String.t()], map()) :: {:ok, :h264 | :mjpeg} | {:error, String.t()}
  def decide(lines, %{kind: :v4l2, device: device, codec: wanted} = source) do
    formats = formats(lines)
    offered = Map.new(formats, &{&1.codec, &1})

    candidates = if wanted == :auto, do: [:h264, :mjpeg], else: [wanted]

    case Enum.find(candidates, &Map.has_key?(offered, Atom.to_string(&1))) do
      nil when formats == [] ->
        {:error, no_formats(device, lines)}

      nil ->
        names = formats |> Enum.map(& &1.codec) |> Enum.join(", ")

        if wanted == :auto,
          do:
            {:error,
             "#{device} offers neither H.264 nor MJPEG (only #{names}), and video is not " <>
               "re-encoded on the vehicle"},
          else: {:error, "#{device} does not offer #{label(wanted)} (it offers #{names})"}

      codec ->
        check_size(codec, Map.fetch!(offered, Atom.to_string(codec)), source)
    end
  end

  defp check_size(codec, %{sizes: :range}, _source), do: {:ok, codec}

  defp check_size(codec, %{sizes: sizes}, %{device: device, width: w, height: h}) do
    if {w, h} in sizes or sizes == [] do
      {:ok, codec}
    else
      listed = Enum.map_join(sizes, " ", fn {w, h} -> "#{w}x#{h}" end)

      {:error,
       "#{device} does not send #{label(codec)} at #{w}x#{h} (it does at #{listed}): " <>
         "choose one with @WxH"}
    end
  end

  # ffmpeg could not open the device: its last line says why
  defp no_formats(device, lines) do
    case lines |> Enum.reject(&(String.trim(&1) == "")) |> List.last() do
      nil -> "#{device}: no formats listed"
      line -> "#{device}: no formats listed (ffmpeg: #{String.trim(line)})"
    end
  end

  defp label(:h264), do: "H.264"
  defp label(:mjpeg), do: "MJPEG"
end
