defmodule Neptunus.Dive.Boundary do
  @moduledoc """
  When a dive ends and the next begins (pure), decided on the entries the recorder writes.

  A dive begins when the recorder starts (the node or the vehicle started, or recording
  resumed after the disk had no room), and again when a pilot takes the helm after it has
  been free for `gap_ms` or more (`NEPTUNUS_DIVE_GAP_MIN`, default 10 min; 0: never) in a
  dive that already had a pilot. So a server that runs for days records one dive per time
  in the water, and everything between two dives — the vehicle on deck, being carried,
  waiting — stays in the dive before (nothing is ever left unrecorded). A dive that had no
  pilot yet keeps the time before its first grant: the checks on deck belong to the dive
  they precede.

  Nothing but `helm` entries matters: `state` `"piloted"` (or the takeover states, in which
  a pilot still holds the helm) is piloted, `"free"` and `"requested"` without a pilot are
  free.
  """

  @typedoc """
  * `gap_ms` — the free time that ends a dive (nil: never)
  * `piloted` — the dive has had a pilot
  * `free_since` — when the helm became free (wall ms), nil while piloted
  """
  @type t :: %__MODULE__{
          gap_ms: pos_integer() | nil,
          piloted: boolean(),
          free_since: integer() | nil
        }
  defstruct [:gap_ms, :free_since, piloted: false]

  @doc "The state at a dive's start (a dive starts with the helm free, as far as it knows)."
  @spec new(non_neg_integer() | nil, integer()) :: t()
  def new(gap_ms, now_ms) do
    gap = if gap_ms in [nil, 0], do: nil, else: gap_ms
    %__MODULE__{gap_ms: gap, free_since: now_ms}
  end

  @doc """
  Takes an entry: `{:new_dive, state}` when it begins a new dive (the entry is the new dive's
  first), else `{:same, state}`.

      iex> alias Neptunus.Dive.Boundary
      iex> b = Boundary.new(600_000, 0)
      iex> piloted = %{state: "piloted", pilot: %{name: "ada"}}
      iex> free = %{state: "free", pilot: nil}
      iex> {:same, b} = Boundary.event(b, {1_000, "helm", piloted})
      iex> {:same, b} = Boundary.event(b, {2_000, "helm", free})
      iex> {:same, b} = Boundary.event(b, {60_000, "helm", piloted})
      iex> {:same, b} = Boundary.event(b, {70_000, "helm", free})
      iex> {:new_dive, b} = Boundary.event(b, {670_000, "helm", piloted})
      iex> b.piloted
      true
  """
  @spec event(t(), {integer(), String.t(), map()}) :: {:same | :new_dive, t()}
  def event(%__MODULE__{} = b, {at, "helm", payload}) when is_map(payload) do
    piloted? = piloted?(payload)

    cond do
      piloted? and b.free_since != nil and b.piloted and b.gap_ms != nil and
          at - b.free_since >= b.gap_ms ->
        {:new_dive, %{b | piloted: true, free_since: nil}}

      piloted? ->
        {:same, %{b | piloted: true, free_since: nil}}

      b.free_since == nil ->
        {:same, %{b | free_since: at}}

      true ->
        {:same, b}
    end
  end

  def event(b, _entry), do: {:same, b}

  defp piloted?(payload) do
    pilot = Map.get(payload, :pilot, Map.get(payload, "pilot"))
    state = Map.get(payload, :state, Map.get(payload, "state"))
    state in ["piloted", "takeover"] or (is_map(pilot) and state != "free")
  end
end
