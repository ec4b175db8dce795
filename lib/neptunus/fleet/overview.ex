defmodule Neptunus.Fleet.Overview do
  @moduledoc """
  The fleet overview's live feed: once a second, while this node has clients of topic
  `"fleet"` (the fleet channel), reads the cluster's directory (`Neptunus.Fleet.directory/0`)
  and, when it differs from the last one sent, broadcasts it to this node's clients as event
  `vehicles` `%{vehicles: [entry]}` (`Neptunus.PubSub.local_broadcast/4`: encoded once per
  node, whatever the number of pages).

  One process per node reads the directory, not one per page: a page on a relay node costs
  the vehicle nodes nothing, and a thousand pages cost what one does. Depth and heading are
  rounded (`summarize/1`: cm, mrad) so that sensor noise below what a page shows does not
  push an update. Between two reads, `unreachable` and `reachable` (from
  `Neptunus.Fleet.Directory`, on the same topic) tell pages at once.
  """
  use GenServer

  alias Neptunus.PubSub

  @topic "fleet"
  @default_period_ms 1_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{period_ms: pos_integer(), last: [map()] | nil}
    @enforce_keys [:period_ms]
    defstruct [:period_ms, last: nil]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts \\ []), do: GenServer.start_link(__MODULE__, opts, name: __MODULE__)

  @doc """
  The directory as the overview sends it: depth rounded to 0.01 m, heading to 0.001 rad,
  everything else as is (pure).
  """
  @spec summarize([Neptunus.Fleet.entry()]) :: [Neptunus.Fleet.entry()]
  def summarize(entries) when is_list(entries) do
    Enum.map(entries, fn entry ->
      %{entry | depth: round_to(entry.depth, 100), heading: round_to(entry.heading, 1000)}
    end)
  end

  @doc """
  What to do with a new summary given the last one sent (`nil`: none yet, or no client
  since): `{:send, summary}` when it differs, `:keep` when it does not (pure).
  """
  @spec decide([map()] | nil, [map()]) :: {:send, [map()]} | :keep
  def decide(last, summary) when is_list(summary),
    do: if(summary == last, do: :keep, else: {:send, summary})

  defp round_to(value, per_unit) when is_number(value), do: round(value * per_unit) / per_unit
  defp round_to(_value, _per_unit), do: nil

  @doc "Reads the directory now and sends it if it changed (tests; a page waits for the tick)."
  @spec refresh() :: :ok
  def refresh, do: GenServer.call(__MODULE__, :refresh)

  @impl true
  def init(opts) do
    period = Keyword.get(opts, :period_ms, @default_period_ms)

    unless is_integer(period) and period > 0,
      do:
        raise(
          ArgumentError,
          "Fleet.Overview period_ms must be a positive integer, got: #{inspect(period)}"
        )

    Process.send_after(self(), :tick, period)
    {:ok, %State{period_ms: period}}
  end

  @impl true
  def handle_call(:refresh, _from, state), do: {:reply, :ok, update(state)}

  @impl true
  def handle_info(:tick, state) do
    Process.send_after(self(), :tick, state.period_ms)
    {:noreply, update(state)}
  end

  def handle_info(_msg, state), do: {:noreply, state}

  defp update(state) do
    if clients?() do
      case decide(state.last, summarize(Neptunus.Fleet.directory())) do
        :keep ->
          state

        {:send, summary} ->
          PubSub.local_broadcast(@topic, "vehicles", %{vehicles: summary})
          %{state | last: summary}
      end
    else
      # the next client gets the directory with its join; after it, changes
      %{state | last: nil}
    end
  end

  # This node's pages on topic "fleet" (the connections PubSub serves as fastlane).
  defp clients? do
    scope = PubSub.scope()

    :pg.get_local_members(scope, {:fastlane, @topic}) != [] or
      :pg.get_local_members(scope, {:fastlane_first, @topic}) != []
  end
end
