defmodule Neptunus.Dive.Replay do
  @moduledoc """
  What a replay reads of a dive besides its entries (those are the `jsonl` export): the
  video's layout — its segments, each with its stream's description, its time span and the
  times of its keyframes (where a player can start) — and the frames of a time window, in
  the video WebSocket's frame format (`Neptunus.Camera.Frame`, docs/API.md "Video"), so the
  page decodes a replayed frame as a live one. Reading only: a replay never touches the live
  vehicle.
  """

  alias Neptunus.Camera.Frame
  alias Neptunus.Dive
  alias Neptunus.Dive.Video

  @max_window_ms 120_000

  @doc """
  The video of the dive at `path`: `%{segments: [...], problems: [...]}`, each segment
  `%{n, codec, width, height, fps, generation, avc, first_us, last_us, frames, keyframes}`
  (`keyframes` their arrival times, µs) — segments with no readable frame are left out, and
  `problems` says what could not be read. A legacy recording has no video.
  """
  @spec video(Path.t()) :: %{segments: [map()], problems: [String.t()]}
  def video(path) do
    segments = path |> Dive.video_folder() |> Video.segments()

    %{
      segments:
        for s <- segments, s.frames != [] do
          %{
            n: s.n,
            codec: s.codec,
            width: s.info["width"],
            height: s.info["height"],
            fps: s.info["fps"],
            generation: s.info["generation"],
            avc: s.info["avc"],
            first_us: s.first_us,
            last_us: s.last_us,
            frames: length(s.frames),
            keyframes: for(f <- s.frames, f.keyframe, do: f.at_us)
          }
        end,
      problems: Enum.flat_map(segments, & &1.problems)
    }
  end

  @doc """
  Checks a window's bounds (text, as a query string gives them; ms since the epoch):
  `{:ok, from_ms, to_ms}`, at most #{div(@max_window_ms, 1000)} s long.
  """
  @spec window(term(), term()) :: {:ok, integer(), integer()} | Dive.error()
  def window(from, to) do
    with {:ok, from} <- ms("from", from),
         {:ok, to} <- ms("to", to) do
      cond do
        to < from ->
          {:error, :invalid, "to must not be before from"}

        to - from > @max_window_ms ->
          {:error, :invalid, "a window is at most #{div(@max_window_ms, 1000)} s"}

        true ->
          {:ok, from, to}
      end
    end
  end

  defp ms(name, text) do
    case is_binary(text) && Integer.parse(text) do
      {n, ""} when n >= 0 ->
        {:ok, n}

      _ ->
        {:error, :invalid, "#{name} must be a time in ms since the epoch, got #{inspect(text)}"}
    end
  end

  @doc """
  The frames to show the dive's video from `from_ms` to `to_ms`: from the last keyframe at or
  before `from_ms` (a decoder starts there) to the last frame at or before `to_ms`, lazily,
  each as a 4-byte big-endian length and the frame (header and payload, as the video
  WebSocket sends it: the recorded arrival and capture times, the stream's generation, the
  frame's number in its segment's stream).
  """
  @spec frames(Path.t(), integer(), integer()) :: Enumerable.t()
  def frames(path, from_ms, to_ms) do
    folder = Dive.video_folder(path)
    segments = Video.segments(folder)

    segments
    |> Video.window(from_ms * 1000, to_ms * 1000)
    |> Stream.flat_map(fn {segment, frames} ->
      generation = segment.info["generation"] || 0
      first_seq = segment.info["first_seq"] || 0
      numbered = Map.new(Enum.with_index(segment.frames), fn {f, i} -> {f.offset, i} end)
      kind = if segment.codec == "h264", do: :h264, else: :jpeg

      %{segment | frames: frames}
      |> Video.payloads()
      |> Stream.map(fn {_s, f, payload} ->
        frame =
          Frame.new(kind, payload,
            keyframe: f.keyframe,
            first: false,
            generation: generation,
            seq: first_seq + Map.fetch!(numbered, f.offset),
            arrival_us: f.at_us,
            capture_us: f.capture_us
          )

        [<<byte_size(frame.data)::32>>, frame.data]
      end)
    end)
  end
end
