defmodule Neptunus.Camera.Snapshot do
  @moduledoc """
  Snapshots: the camera's current picture at full resolution, saved as a JPEG next to the
  vehicle's recordings — `<dir>/<vehicle>/snapshots/<name>.jpg`, where `dir` is the
  recordings' directory (`NEPTUNUS_RECORDINGS`).

  The name says the vehicle, the time (UTC, to the millisecond), the depth and the heading
  (`name/4`): `neptunus-1-20261128-081500.123Z-2.31m-123deg.jpg` (`na` for a value not
  known). The same and more are in the JPEG's comment segment (`COM`, `comment/1`): a JSON
  object with `vehicle`, `taken_at` (ISO 8601), `depth_m`, `heading_deg`, `camera`, `width`,
  `height`, readable with `exiftool`, `identify -verbose` or `rdjpgcom`.

  An MJPEG camera's snapshot is its newest image. An H.264 camera's is decoded by ffmpeg on
  demand from the camera's frames since the last keyframe (`Neptunus.Vehicle.Camera.pictures/1`),
  the newest picture kept. This runs in the caller's process — a request's, or a task of a
  WebSocket's — never in the camera's, the board's or the helm's.
  """

  alias Neptunus.Camera.MJPEG
  alias Neptunus.Vehicle.{Camera, Telemetry}

  @name_re ~r/\A(?<vehicle>[A-Za-z0-9_-]{1,32})-(?<date>\d{8}-\d{6}\.\d{3})Z-(?<depth>\d+\.\d{2}|na)m-(?<heading>\d{3}|na)deg(?:-\d+)?\.jpg\z/
  @decode_timeout_s 30

  @typedoc "A saved snapshot, as the API lists it."
  @type t :: %{
          vehicle: String.t(),
          name: String.t(),
          bytes: non_neg_integer(),
          taken_at: integer(),
          depth: float() | nil,
          heading: float() | nil
        }

  @doc """
  Takes a snapshot of vehicle `id`'s camera (on the vehicle's node) into `dir`:
  `{:ok, snapshot}` with the saved file's `t:t/0` and the picture's `width` and `height`, or
  `{:error, reason}`. Option `:ffmpeg` (default found on the path).
  """
  @spec take(String.t(), Path.t(), keyword()) :: {:ok, map()} | {:error, String.t()}
  def take(id, dir, opts \\ []) do
    ffmpeg = Keyword.get_lazy(opts, :ffmpeg, fn -> System.find_executable("ffmpeg") end)

    with {:ok, pictures} <- Camera.pictures(id),
         {:ok, jpeg} <- jpeg(pictures, ffmpeg) do
      taken_at = Neptunus.Clock.wall_ms()
      {depth, heading} = where(id)
      name = name(id, taken_at, depth, heading)

      {width, height} = MJPEG.size(jpeg) || {pictures.width, pictures.height}

      meta = %{
        vehicle: id,
        taken_at: iso8601(taken_at),
        depth_m: depth && Float.round(depth, 3),
        heading_deg: heading && Float.round(heading * 180 / :math.pi(), 2),
        camera: pictures[:source],
        width: width,
        height: height
      }

      jpeg = with_comment(jpeg, comment(meta))

      with {:ok, name} <- save(dir, id, name, jpeg) do
        {:ok,
         %{
           vehicle: id,
           name: name,
           bytes: byte_size(jpeg),
           taken_at: taken_at,
           depth: depth,
           heading: heading,
           width: width,
           height: height
         }}
      end
    end
  end

  # depth (m) and heading (rad) now: the estimate, else the measurement
  defp where(id) do
    case Telemetry.latest(id) do
      %{} = t ->
        {value(t, :depth), value(t, :heading)}

      _ ->
        {nil, nil}
    end
  catch
    :exit, _ -> {nil, nil}
  end

  defp value(telemetry, key) do
    case get_in(telemetry, [:estimate, key]) || get_in(telemetry, [:measurement, key]) do
      x when is_number(x) -> x * 1.0
      _ -> nil
    end
  end

  defp jpeg(%{codec: :mjpeg, frames: [jpeg | _]}, _ffmpeg), do: {:ok, jpeg}
  defp jpeg(%{codec: :h264}, nil), do: {:error, "ffmpeg is not installed: no snapshot of H.264"}

  defp jpeg(%{codec: :h264, frames: frames}, ffmpeg) do
    base = Path.join(System.tmp_dir!(), "neptunus-snapshot-#{System.unique_integer([:positive])}")
    input = base <> ".h264"
    output = base <> ".jpg"

    try do
      File.write!(input, frames)
      # every decoded picture written over the last: the newest stays
      args =
        ["#{@decode_timeout_s}", ffmpeg] ++
          ~w(-nostdin -hide_banner -loglevel error -f h264 -i) ++
          [input] ++ ~w(-update 1 -q:v 2 -y) ++ [output]

      case System.cmd("timeout", args, stderr_to_stdout: true) do
        {_, 0} ->
          case File.read(output) do
            {:ok, jpeg} when byte_size(jpeg) > 0 -> {:ok, jpeg}
            _ -> {:error, "ffmpeg decoded no picture from the camera's frames"}
          end

        {out, status} ->
          {:error, "ffmpeg could not decode the camera's frames (#{status}): #{String.trim(out)}"}
      end
    after
      File.rm(input)
      File.rm(output)
    end
  end

  defp save(dir, id, name, jpeg) do
    folder = folder(dir, id)

    with :ok <- mkdir(folder) do
      name = free_name(folder, name, 1)
      path = Path.join(folder, name)
      tmp = path <> ".tmp"

      case File.write(tmp, jpeg) do
        :ok ->
          File.rename!(tmp, path)
          {:ok, name}

        {:error, reason} ->
          File.rm(tmp)
          {:error, "cannot save the snapshot in #{folder}: #{:file.format_error(reason)}"}
      end
    end
  end

  defp mkdir(folder) do
    case File.mkdir_p(folder) do
      :ok ->
        :ok

      {:error, reason} ->
        {:error, "cannot save snapshots in #{folder}: #{:file.format_error(reason)}"}
    end
  end

  # two snapshots in the same millisecond: -2, -3, …
  defp free_name(folder, name, n) do
    candidate = if n == 1, do: name, else: String.replace_suffix(name, ".jpg", "-#{n}.jpg")

    if File.exists?(Path.join(folder, candidate)),
      do: free_name(folder, name, n + 1),
      else: candidate
  end

  @doc "Where vehicle `id`'s snapshots are, under the recordings' directory `dir`."
  @spec folder(Path.t(), String.t()) :: Path.t()
  def folder(dir, id), do: Path.join([dir, id, "snapshots"])

  @doc """
  A snapshot's file name (pure): the vehicle, the UTC time to the millisecond, the depth
  (m, two decimals) and the heading (degrees, three digits).

      iex> Neptunus.Camera.Snapshot.name("rov-1", 1_795_000_000_123, 2.3456, :math.pi() / 2)
      "rov-1-20261118-110640.123Z-2.35m-090deg.jpg"
      iex> Neptunus.Camera.Snapshot.name("rov-1", 0, nil, nil)
      "rov-1-19700101-000000.000Z-nam-nadeg.jpg"
  """
  @spec name(String.t(), integer(), float() | nil, float() | nil) :: String.t()
  def name(id, taken_at_ms, depth, heading) do
    time =
      taken_at_ms
      |> DateTime.from_unix!(:millisecond)
      |> Calendar.strftime("%Y%m%d-%H%M%S.%fZ")
      |> String.replace(~r/\.(\d{3})\d*Z/, ".\\1Z")

    depth = if depth, do: :erlang.float_to_binary(max(depth, 0.0), decimals: 2), else: "na"

    heading =
      if heading do
        deg = rem(round(heading * 180 / :math.pi()), 360)

        deg
        |> then(&if(&1 < 0, do: &1 + 360, else: &1))
        |> Integer.to_string()
        |> String.pad_leading(3, "0")
      else
        "na"
      end

    "#{id}-#{time}-#{depth}m-#{heading}deg.jpg"
  end

  @doc """
  Whether `name` is a snapshot name of vehicle `vehicle` (what the API serves: nothing
  else in the folder, no path).

      iex> Neptunus.Camera.Snapshot.valid?("rov-1", "rov-1-20261117-083320.123Z-2.35m-090deg.jpg")
      true
      iex> Neptunus.Camera.Snapshot.valid?("rov-1", "../rov-1-20261117-083320.123Z-2.35m-090deg.jpg")
      false
  """
  @spec valid?(String.t(), String.t()) :: boolean()
  def valid?(vehicle, name) do
    case Regex.named_captures(@name_re, name) do
      %{"vehicle" => ^vehicle} -> true
      _ -> false
    end
  end

  @doc "Vehicle `vehicle`'s snapshots in `dir` (all vehicles' without one), newest first."
  @spec list(Path.t(), String.t() | nil) :: [t()]
  def list(dir, vehicle \\ nil) do
    vehicles =
      case vehicle do
        nil ->
          dir
          |> File.ls()
          |> then(fn
            {:ok, names} -> names
            _ -> []
          end)

        id ->
          [id]
      end

    vehicles
    |> Enum.flat_map(fn id ->
      folder = folder(dir, id)

      case File.ls(folder) do
        {:ok, names} -> for name <- names, valid?(id, name), do: entry(folder, id, name)
        {:error, _} -> []
      end
    end)
    |> Enum.reject(&is_nil/1)
    |> Enum.sort_by(& &1.taken_at, :desc)
  end

  defp entry(folder, id, name) do
    %{"date" => date, "depth" => depth, "heading" => heading} =
      Regex.named_captures(@name_re, name)

    case File.stat(Path.join(folder, name)) do
      {:ok, %File.Stat{size: size}} ->
        %{
          vehicle: id,
          name: name,
          bytes: size,
          taken_at: parse_time(date),
          depth: if(depth == "na", do: nil, else: String.to_float(depth)),
          heading:
            if(heading == "na", do: nil, else: String.to_integer(heading) * :math.pi() / 180)
        }

      {:error, _} ->
        nil
    end
  end

  defp parse_time(
         <<y::binary-4, mo::binary-2, d::binary-2, "-", h::binary-2, mi::binary-2, s::binary-2,
           ".", ms::binary-3>>
       ) do
    {:ok, dt, 0} = DateTime.from_iso8601("#{y}-#{mo}-#{d}T#{h}:#{mi}:#{s}.#{ms}Z")
    DateTime.to_unix(dt, :millisecond)
  end

  defp iso8601(ms), do: ms |> DateTime.from_unix!(:millisecond) |> DateTime.to_iso8601()

  @doc "The JPEG comment of a snapshot: its metadata as JSON (pure)."
  @spec comment(map()) :: String.t()
  def comment(meta), do: Neptunus.JSON.encode!(meta)

  @doc """
  `jpeg` with a comment segment (`FF FE`, at most 65 533 bytes of text) after its start (and
  after its JFIF segment, which must come first).

      iex> jpeg = <<0xFF, 0xD8, 0xFF, 0xDA, 0, 2, 0xFF, 0xD9>>
      iex> Neptunus.Camera.Snapshot.with_comment(jpeg, "hi")
      <<0xFF, 0xD8, 0xFF, 0xFE, 0, 4, "hi", 0xFF, 0xDA, 0, 2, 0xFF, 0xD9>>
  """
  @spec with_comment(binary(), String.t()) :: binary()
  def with_comment(<<0xFF, 0xD8, rest::binary>>, text) do
    text = binary_part(text, 0, min(byte_size(text), 65_533))
    com = <<0xFF, 0xFE, byte_size(text) + 2::16, text::binary>>

    case rest do
      <<0xFF, 0xE0, len::16, app0::binary-size(len - 2), after_app0::binary>> when len >= 2 ->
        <<0xFF, 0xD8, 0xFF, 0xE0, len::16, app0::binary, com::binary, after_app0::binary>>

      _ ->
        <<0xFF, 0xD8, com::binary, rest::binary>>
    end
  end
end
