defmodule Neptunus.Vehicle.Board.Test do
  @moduledoc """
  A board for tests that reports everything it is told to the test process (test doubles
  send messages; there is no mocking library). Use `board: Neptunus.Vehicle.Board.Test` in a vehicle map and `report_to: self()`.

      start_supervised!({Neptunus.Vehicle.Supervisor,
                         %{id: id, board: Neptunus.Vehicle.Board.Test, report_to: self()}})

  Messages to `report_to` (required):

    * `{:board, id, {:started, thrusters}}` — the board (re)started, thrusters neutral
    * `{:board, id, {:go, thrusters}}` — every `go` cast, as received (the demand for a
      vehicle whose `capabilities` say `allocation: :vehicle`)
    * `{:board, id, :keepalive}` — every keepalive from control
    * `{:board, id, {:lights | :laser | :tilt, value}}` — every lights, laser, tilt command

  `sample/2` makes it report a sample to the vehicle's navigation as a real board would
  (through `Board.sample/3`), and
  `set_link/3` sets what `link_status/1` answers.
  """
  use GenServer

  alias Neptunus.Allocation
  alias Neptunus.Vehicle.Board

  @behaviour Board

  @impl Board
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Board.via(id))
  end

  @doc """
  The three-thruster vehicle's, unless the vehicle's options say otherwise
  (`capabilities: %{...}`, merged over them: e.g. `%{axes: [:surge, :sway, :heave, :yaw],
  allocation: :vehicle}` for a vehicle that allocates itself, whose `go` gets the demand).
  """
  @impl Board
  def capabilities(opts),
    do: Map.merge(Board.thesis_capabilities(), Map.new(Keyword.get(opts, :capabilities, %{})))

  @impl Board
  def go(id, output), do: GenServer.cast(Board.via(id), {:go, output})

  @impl Board
  def keepalive(id), do: GenServer.cast(Board.via(id), :keepalive)

  @impl Board
  def link_status(id), do: GenServer.call(Board.via(id), :link_status)

  @impl Board
  def lights(id, n), do: GenServer.cast(Board.via(id), {:lights, n})

  @impl Board
  def laser(id, n), do: GenServer.cast(Board.via(id), {:laser, n})

  @impl Board
  def tilt(id, rad), do: GenServer.cast(Board.via(id), {:tilt, rad})

  @doc "Reports `sample` (a `Board.sample()`) to vehicle `id`'s navigation."
  @spec sample(String.t(), Board.sample()) :: :ok
  def sample(id, sample) do
    :ok = GenServer.call(Board.via(id), {:sample, sample})
    # navigation passes samples on asynchronously: a call after the board's cast returns once
    # it has, so the caller sees the sample in telemetry right away
    _ = Neptunus.Vehicle.Navigation.status(id)
    :ok
  end

  @doc "Sets the link state `link_status/1` reports."
  @spec set_link(String.t(), boolean(), String.t()) :: :ok
  def set_link(id, up, reason), do: GenServer.call(Board.via(id), {:set_link, up, reason})

  @impl true
  def init(opts) do
    state = %{
      id: Keyword.fetch!(opts, :id),
      report_to: Keyword.fetch!(opts, :report_to),
      thrusters: Allocation.neutral(),
      link: %{up: true, reason: "test"}
    }

    report(state, {:started, state.thrusters})
    {:ok, state}
  end

  @impl true
  def handle_cast({:go, thrusters}, state) do
    report(state, {:go, thrusters})
    {:noreply, %{state | thrusters: thrusters}}
  end

  def handle_cast({device, value}, state) when device in [:lights, :laser, :tilt] do
    report(state, {device, value})
    {:noreply, state}
  end

  def handle_cast(:keepalive, state) do
    report(state, :keepalive)
    {:noreply, state}
  end

  @impl true
  def handle_call({:sample, sample}, _from, state) do
    Board.sample(state.id, sample)
    {:reply, :ok, state}
  end

  def handle_call({:set_link, up, reason}, _from, state),
    do: {:reply, :ok, %{state | link: %{up: up, reason: reason}}}

  def handle_call(:link_status, _from, state), do: {:reply, state.link, state}

  defp report(state, event), do: send(state.report_to, {:board, state.id, event})
end
