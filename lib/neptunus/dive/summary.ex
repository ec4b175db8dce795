defmodule Neptunus.Dive.Summary do
  @moduledoc """
  A dive's summary (pure): what the listing shows of a dive without reading it — when it
  started and ended, how long it lasted, how deep it went, who piloted, how many stops and
  snapshots. The recorder folds every entry it writes into it (`add/2`) and saves it in the
  dive's folder (`summary.json`, `to_map/1`); a dive whose summary was not closed (its node
  was killed) gets it again from its entries (`Neptunus.Dive.repair/3` folds them the same
  way).

  Depth is the navigation estimate's, else the accepted measurement's (m, positive down).
  A pilot counts once, by name, in the order they first took the helm. A stop is a
  `stopped` event (thrusters neutral, for safety or by request).
  """

  @typedoc """
  * `started_at`, `ended_at` — the first and last entry's wall clock (ms); `started_at` is the
    dive's start when no entry came yet
  * `entries`, `telemetry` — entries written, of which telemetry
  * `max_depth` — m, nil when no depth was known
  * `pilots` — names, first grant first; `stops`, `snapshots` — counts
  """
  @type t :: %__MODULE__{
          started_at: integer(),
          ended_at: integer() | nil,
          entries: non_neg_integer(),
          telemetry: non_neg_integer(),
          max_depth: float() | nil,
          pilots: [String.t()],
          stops: non_neg_integer(),
          snapshots: non_neg_integer()
        }
  @enforce_keys [:started_at]
  defstruct [
    :started_at,
    :ended_at,
    :max_depth,
    entries: 0,
    telemetry: 0,
    pilots: [],
    stops: 0,
    snapshots: 0
  ]

  @doc "The summary of a dive started at `started_at` (wall clock, ms), before any entry."
  @spec new(integer()) :: t()
  def new(started_at) when is_integer(started_at), do: %__MODULE__{started_at: started_at}

  @doc """
  The summary with one more entry `{at, event, payload}` (as the recorder writes them).

      iex> alias Neptunus.Dive.Summary
      iex> s = Summary.new(1_000)
      iex> s = Summary.add(s, {1_050, "telemetry", %{estimate: %{depth: 2.5}}})
      iex> s = Summary.add(s, {1_100, "helm", %{state: "piloted", pilot: %{name: "ada"}}})
      iex> s = Summary.add(s, {1_150, "stopped", %{reason: "deadman"}})
      iex> s = Summary.add(s, {1_200, "telemetry", %{estimate: %{depth: nil}, measurement: %{depth: 3.0}}})
      iex> Map.take(s, [:max_depth, :pilots, :stops, :entries, :telemetry, :ended_at])
      %{max_depth: 3.0, pilots: ["ada"], stops: 1, entries: 4, telemetry: 2, ended_at: 1_200}
  """
  @spec add(t(), {integer(), String.t(), map()}) :: t()
  def add(%__MODULE__{} = s, {at, event, payload}) when is_integer(at) and is_map(payload) do
    s = %{s | entries: s.entries + 1, ended_at: max(at, s.ended_at || at)}

    case event do
      "telemetry" ->
        %{s | telemetry: s.telemetry + 1, max_depth: deeper(s.max_depth, depth(payload))}

      "helm" ->
        %{s | pilots: add_pilot(s.pilots, pilot_name(payload))}

      "stopped" ->
        %{s | stops: s.stops + 1}

      "snapshot" ->
        %{s | snapshots: s.snapshots + 1}

      _ ->
        s
    end
  end

  def add(s, _entry), do: s

  @doc """
  Whether `event` changes more of the summary than its end and counts (so the recorder saves
  it at once, not with its periodic save).

      iex> Neptunus.Dive.Summary.notable?("stopped")
      true
      iex> Neptunus.Dive.Summary.notable?("telemetry")
      false
  """
  @spec notable?(String.t()) :: boolean()
  def notable?(event), do: event in ["helm", "stopped", "snapshot"]

  defp depth(payload) do
    case get(payload, [:estimate, :depth]) do
      d when is_number(d) ->
        d

      _ ->
        case get(payload, [:measurement, :depth]) do
          d when is_number(d) -> d
          _ -> nil
        end
    end
  end

  # a payload's field by atom keys (as recorded) or string keys (as read back from JSON)
  defp get(value, []), do: value

  defp get(%{} = map, [key | rest]) do
    case Map.fetch(map, key) do
      {:ok, v} -> get(v, rest)
      :error -> map |> Map.get(Atom.to_string(key)) |> get(rest)
    end
  end

  defp get(_value, _path), do: nil

  defp deeper(nil, nil), do: nil
  defp deeper(max, nil), do: max
  defp deeper(nil, d), do: d * 1.0
  defp deeper(max, d), do: max(max, d * 1.0)

  defp pilot_name(payload) do
    case get(payload, [:pilot, :name]) do
      name when is_binary(name) -> name
      _ -> nil
    end
  end

  defp add_pilot(pilots, nil), do: pilots
  defp add_pilot(pilots, name), do: if(name in pilots, do: pilots, else: pilots ++ [name])

  @doc """
  The summary as saved in `summary.json` and listed: times in ms since the epoch,
  `duration_ms` from the first to the last entry, `closed` whether the recorder finished
  the dive (false while it records, or when its node was killed before it could).
  """
  @spec to_map(t(), boolean()) :: map()
  def to_map(%__MODULE__{} = s, closed) do
    %{
      started_at: s.started_at,
      ended_at: s.ended_at,
      duration_ms: if(s.ended_at, do: max(s.ended_at - s.started_at, 0), else: 0),
      max_depth: s.max_depth,
      pilots: s.pilots,
      stops: s.stops,
      snapshots: s.snapshots,
      entries: s.entries,
      telemetry: s.telemetry,
      closed: closed
    }
  end
end
