defmodule Neptunus.Vehicle.Telemetry do
  @moduledoc """
  A vehicle's latest state and its `telemetry` broadcast on `"vehicle:<id>"`.

  It keeps the last board sample and the last control output, and publishes the combined
  payload at `telemetry_hz` (default 20 Hz) on absolute deadlines of the monotonic clock
  (re-arming a relative timer would drift). The payload is documented in `docs/API.md`:

      %{t: s, sent_at: epoch ms,
        measurement: %{depth, heading, roll, pitch, voltage, current},
        sim: %{x, y, z, phi, theta, psi, u, v, w, p, q, r} | nil,
        command: %{surge, heave, yaw},
        thrusters: %{port, vertical, starboard, port_us, vertical_us, starboard_us}}

  SI units (m, m/s, rad, rad/s, V, A); heading in [0, 2π). `t` is the vehicle's clock,
  `sent_at` the wall clock at broadcast (for latency measurements only).
  """
  use GenServer

  alias Neptunus.{Allocation, Periodic, PubSub}
  alias Neptunus.Vehicle.Board

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            periodic: Periodic.t(),
            sample: Board.sample() | nil,
            command: Allocation.motion(),
            thrusters: map()
          }
    @enforce_keys [:id, :topic, :periodic, :command, :thrusters]
    defstruct [:id, :topic, :periodic, :sample, :command, :thrusters]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: via(Keyword.fetch!(opts, :id)))
  end

  @doc "The topic of vehicle `id`."
  @spec topic(String.t()) :: String.t()
  def topic(id), do: "vehicle:" <> id

  @doc "Reports a board sample (called by the board)."
  @spec sample(String.t(), Board.sample()) :: :ok
  def sample(id, sample), do: GenServer.cast(via(id), {:sample, sample})

  @doc "Reports the control output (called by control)."
  @spec control(String.t(), Allocation.motion(), Allocation.thrusters()) :: :ok
  def control(id, command, thrusters), do: GenServer.cast(via(id), {:control, command, thrusters})

  @doc "The latest telemetry payload, or nil before the first board sample."
  @spec latest(String.t()) :: map() | nil
  def latest(id), do: GenServer.call(via(id), :latest)

  defp via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    hz = Keyword.get(opts, :hz, Application.get_env(:neptunus, :telemetry_hz, 20))

    state = %State{
      id: id,
      topic: topic(id),
      periodic: Periodic.new(hz),
      command: %{surge: 0.0, heave: 0.0, yaw: 0.0},
      thrusters: Allocation.with_us(Allocation.neutral())
    }

    Periodic.arm(state.periodic, :tick)
    {:ok, state}
  end

  @impl true
  def handle_cast({:sample, sample}, state), do: {:noreply, %{state | sample: sample}}

  def handle_cast({:control, command, thrusters}, state) do
    {:noreply, %{state | command: command, thrusters: Allocation.with_us(thrusters)}}
  end

  @impl true
  def handle_call(:latest, _from, state), do: {:reply, payload(state), state}

  @impl true
  def handle_info(:tick, state) do
    case payload(state) do
      nil -> :ok
      payload -> PubSub.broadcast(state.topic, "telemetry", payload)
    end

    # one broadcast per tick; ticks missed during a stall are skipped, not replayed
    {_due, periodic} = Periodic.advance(state.periodic, System.monotonic_time())
    Periodic.arm(periodic, :tick)
    {:noreply, %{state | periodic: periodic}}
  end

  defp payload(%State{sample: nil}), do: nil

  defp payload(%State{sample: sample} = state) do
    %{
      t: sample.t,
      sent_at: System.os_time(:microsecond) / 1000,
      measurement: sample.measurement,
      sim: sample.sim,
      command: state.command,
      thrusters: state.thrusters
    }
  end
end
