defmodule Neptunus.Dive.ASS do
  @moduledoc """
  A dive's telemetry as an `.ass` subtitle track (pure), as Cockpit's recordings carry it:
  one line at the bottom of the picture with the time (UTC), depth, heading, pilot and the
  stops so far, so any video player shows the numbers over the video.

  A cue starts at a telemetry entry's own time (relative to `zero_ms`, the video's first
  frame) and lasts until the next cue: one cue per telemetry entry at least `every_ms`
  (default 200) after the previous cue's, so a cue's start is its telemetry's time (to the
  centisecond ASS writes). Entries before `zero_ms` are left out. Depth and heading are the
  navigation estimate's, else the measurement's; the pilot and the stops come from the
  `helm` and `stopped` entries before the cue.
  """

  @default_every_ms 200

  @doc "The script's head: its info, the style, the events' format."
  @spec header(String.t()) :: iodata()
  def header(title) do
    title = String.replace(title, ~r/[\r\n]/, " ")

    """
    [Script Info]
    Title: #{title}
    ScriptType: v4.00+
    PlayResX: 1280
    PlayResY: 720
    WrapStyle: 2
    ScaledBorderAndShadow: yes

    [V4+ Styles]
    Format: Name, Fontname, Fontsize, PrimaryColour, SecondaryColour, OutlineColour, BackColour, Bold, Italic, Underline, StrikeOut, ScaleX, ScaleY, Spacing, Angle, BorderStyle, Outline, Shadow, Alignment, MarginL, MarginR, MarginV, Encoding
    Style: Telemetry,DejaVu Sans Mono,26,&H00FFFFFF,&H000000FF,&H00000000,&H80000000,0,0,0,0,100,100,0,0,3,1,0,1,16,16,12,1

    [Events]
    Format: Layer, Start, End, Style, Name, MarginL, MarginR, MarginV, Effect, Text
    """
  end

  @doc """
  The cues of `entries` (`{at_ms, event, payload}`, in order), lazily, as `{start_ms, end_ms,
  text}` relative to `zero_ms`; the last one lasts `every_ms`.

      iex> entries = [
      ...>   {900, "telemetry", %{estimate: %{depth: 1.0, heading: 0.0}}},
      ...>   {1_000, "helm", %{state: "piloted", pilot: %{name: "ada"}}},
      ...>   {1_010, "telemetry", %{estimate: %{depth: 1.5, heading: :math.pi() / 2}}},
      ...>   {1_100, "telemetry", %{estimate: %{depth: 1.6, heading: 0.0}}},
      ...>   {1_250, "stopped", %{reason: "deadman"}},
      ...>   {1_260, "telemetry", %{measurement: %{depth: 2.0, heading: nil}}}
      ...> ]
      iex> Neptunus.Dive.ASS.cues(entries, 1_000, 200) |> Enum.to_list()
      [{10, 260, "00:00:01  depth 1.50 m  heading 090°  pilot ada  stops 0"},
       {260, 460, "00:00:01  depth 2.00 m  heading ---  pilot ada  stops 1"}]
  """
  @spec cues(Enumerable.t(), integer(), pos_integer()) :: Enumerable.t()
  def cues(entries, zero_ms, every_ms \\ @default_every_ms) do
    entries
    |> Stream.concat([:end])
    |> Stream.transform(%{pilot: nil, stops: 0, last: nil}, fn
      :end, %{last: nil} = s ->
        {[], s}

      :end, %{last: {start, text}} = s ->
        {[{start, start + every_ms, text}], %{s | last: nil}}

      {_at, "helm", payload}, s ->
        {[], %{s | pilot: pilot(payload)}}

      {_at, "stopped", _payload}, s ->
        {[], %{s | stops: s.stops + 1}}

      {at, "telemetry", payload}, s when at >= zero_ms ->
        start = at - zero_ms

        case s.last do
          {last, _} when start - last < every_ms ->
            {[], s}

          previous ->
            cue = {start, text(at, payload, s)}
            out = if previous, do: [{elem(previous, 0), start, elem(previous, 1)}], else: []
            {out, %{s | last: cue}}
        end

      _entry, s ->
        {[], s}
    end)
  end

  @doc """
  A cue as a `Dialogue:` line.

      iex> Neptunus.Dive.ASS.dialogue({3_725_004, 3_725_204, "x"}) |> IO.iodata_to_binary()
      "Dialogue: 0,1:02:05.00,1:02:05.20,Telemetry,,0,0,0,,x\\n"
  """
  @spec dialogue({integer(), integer(), String.t()}) :: iodata()
  def dialogue({start_ms, end_ms, text}) do
    ["Dialogue: 0,", time(start_ms), ",", time(end_ms), ",Telemetry,,0,0,0,,", text, "\n"]
  end

  @doc """
  An ASS time (h:mm:ss.cc), rounded to the centisecond.

      iex> Neptunus.Dive.ASS.time(61_235)
      "0:01:01.24"
  """
  @spec time(integer()) :: String.t()
  def time(ms) do
    cs = div(max(ms, 0) + 5, 10)
    h = div(cs, 360_000)
    m = div(rem(cs, 360_000), 6000)
    s = div(rem(cs, 6000), 100)
    c = rem(cs, 100)
    "#{h}:#{pad(m)}:#{pad(s)}.#{pad(c)}"
  end

  defp pad(n), do: n |> Integer.to_string() |> String.pad_leading(2, "0")

  defp text(at_ms, payload, s) do
    clock = at_ms |> DateTime.from_unix!(:millisecond) |> Calendar.strftime("%H:%M:%S")

    depth =
      case value(payload, :depth) do
        d when is_number(d) -> :erlang.float_to_binary(d * 1.0, decimals: 2) <> " m"
        _ -> "---"
      end

    heading =
      case value(payload, :heading) do
        h when is_number(h) ->
          deg = rem(round(h * 180 / :math.pi()) + 360, 360)
          (deg |> Integer.to_string() |> String.pad_leading(3, "0")) <> "°"

        _ ->
          "---"
      end

    pilot = if s.pilot, do: escape(s.pilot), else: "none"
    "#{clock}  depth #{depth}  heading #{heading}  pilot #{pilot}  stops #{s.stops}"
  end

  # the estimate's value, else the measurement's
  defp value(payload, key) do
    from = fn section ->
      case Map.get(payload, section) do
        %{} = m -> Map.get(m, key)
        _ -> nil
      end
    end

    case from.(:estimate) do
      v when is_number(v) -> v
      _ -> from.(:measurement)
    end
  end

  defp pilot(payload) do
    case payload do
      %{pilot: %{name: name}} when is_binary(name) -> name
      _ -> nil
    end
  end

  # ASS override blocks and line breaks are not a pilot's name
  defp escape(text), do: String.replace(text, ["{", "}", "\\", "\n", "\r"], " ")
end
