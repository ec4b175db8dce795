defmodule Neptunus.Vehicle.Telemetry do
  @moduledoc """
  A vehicle's latest state and its `telemetry` broadcast on `"vehicle:<id>"`.

  It keeps the last board sample and the last control output, and publishes the combined
  payload at `telemetry_hz` (default 20 Hz) on absolute deadlines of the monotonic clock
  (re-arming a relative timer would drift). The payload — `t`, `sent_at`, the sample's
  `measurement`, `measurement_state`, `estimate`, `wild_points`, `position` and `sim` (from
  navigation), the
  control state's `command`, `thrusters`, `control`, `autopilot` and `axes`, the board's `link`, and the
  parts' reports (`recording`, `camera`) — is defined, field by field, by the wire schema
  (`NeptunusWeb.WireSchema`, type `telemetry`; docs/API.md): a field added here is added there,
  or the conformance test fails.

  The broadcast is paced while someone pilots (`Neptunus.PubSub.broadcast_paced/5`): the
  recorder and the pilot's connection get it at once; with many observers, their
  connections get it in slices of `:fanout_slice` (default 50) every `:fanout_gap_ms`
  (default 2 ms), all within half the period (25 ms at 20 Hz), so a thousand observers
  never hold the vehicle computer's cores for a whole burst while a pilot's command waits
  for one (`bench/control_latency`). Without a pilot, everyone gets it at once.
  """
  use GenServer

  alias Neptunus.{Allocation, Periodic, PubSub}
  alias Neptunus.Vehicle.Board

  @default_hz 20
  @default_fanout_slice 50
  @default_fanout_gap_ms 2

  @no_estimate %{
    depth: nil,
    depth_rate: nil,
    heading: nil,
    yaw_rate: nil,
    roll: nil,
    roll_rate: nil,
    pitch: nil,
    pitch_rate: nil
  }
  @initialising Map.new(Neptunus.Navigation.WildPoints.fields(), &{&1, "initialising"})
  @no_autopilot %{depth: nil, heading: nil, position: nil}
  @no_position %{
    valid: false,
    reason: "no position estimate yet",
    frame: nil,
    epoch: 0,
    north: nil,
    east: nil,
    depth: nil,
    velocity_north: nil,
    velocity_east: nil,
    std_north: nil,
    std_east: nil,
    ellipse: nil,
    origin: nil,
    sources: []
  }

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            periodic: Periodic.t(),
            pace: PubSub.pace(),
            sample: Neptunus.Vehicle.Telemetry.sample() | nil,
            command: map(),
            thrusters: map(),
            control: map() | nil,
            autopilot: map(),
            axes: [Neptunus.Control.Demand.axis()] | nil,
            link: %{
              required(:up) => boolean(),
              required(:reason) => String.t(),
              optional(atom()) => term()
            },
            reports: %{optional(:recording | :camera) => map()}
          }
    @enforce_keys [:id, :topic, :periodic, :pace, :command, :thrusters, :autopilot]
    defstruct [
      :id,
      :topic,
      :periodic,
      :pace,
      :sample,
      :command,
      :thrusters,
      :control,
      :autopilot,
      :axes,
      link: %{up: false, reason: "not known yet"},
      reports: %{}
    ]
  end

  @typedoc """
  What navigation reports: a board sample (`t:Neptunus.Vehicle.Board.sample/0`) whose
  `measurement` holds the accepted values (nil while initialising), with `measurement_state`,
  `estimate` and `wild_points`.
  """
  @type sample :: %{
          required(:t) => float(),
          required(:measurement) => %{optional(atom()) => float() | nil},
          required(:sim) => map() | nil,
          optional(atom()) => term()
        }

  @doc """
  Options: `:id` (required), `:telemetry_hz` (broadcast rate, default #{@default_hz}),
  `:fanout_slice` (default #{@default_fanout_slice}) and `:fanout_gap_ms` (default
  #{@default_fanout_gap_ms}): see the moduledoc.
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: via(Keyword.fetch!(opts, :id)))
  end

  @doc "The topic of vehicle `id`."
  @spec topic(String.t()) :: String.t()
  def topic(id), do: "vehicle:" <> id

  @doc """
  The topic of vehicle `id`'s log entries (the developer logger): the control loop, the
  recorder and the camera publish there, `NeptunusWeb.Channels.LogChannel` serves it.
  """
  @spec log_topic(String.t()) :: String.t()
  def log_topic(id), do: "log:" <> id

  @doc """
  Publishes an entry for vehicle `id`'s developer logger (and its recording) on `log_topic/1`:
  `category` (`"link"`, `"autopilot"`, …), `level` (`"info"`, `"warning"`, `"error"`), the
  message, stamped with the wall clock.
  """
  @spec log(String.t(), String.t(), String.t(), String.t()) :: :ok
  def log(id, category, level, message) do
    PubSub.broadcast(log_topic(id), "log", %{
      category: category,
      level: level,
      message: message,
      at: Neptunus.Clock.wall_ms()
    })

    :ok
  end

  @doc """
  Reports a board sample (called by `Neptunus.Vehicle.Navigation`, with the filtered
  `measurement`, the `estimate` and the `wild_points` counts).
  """
  @spec sample(String.t(), sample()) :: :ok
  def sample(id, sample), do: GenServer.cast(via(id), {:sample, sample})

  @doc """
  Reports the control state (called by `Neptunus.Vehicle.Control` after every change and
  control-loop tick): `%{command, thrusters, control, autopilot}` and the `axes` the pilot may
  command (see the moduledoc).
  """
  @spec control(String.t(), %{
          required(:command) => map(),
          required(:thrusters) => Allocation.thrusters(),
          required(:control) => map(),
          required(:autopilot) => map(),
          optional(:axes) => [Neptunus.Control.Demand.axis()]
        }) :: :ok
  def control(id, %{command: _, thrusters: _, control: _, autopilot: _} = state),
    do: GenServer.cast(via(id), {:control, state})

  @doc """
  Reports the board link's state (called by boards with a link when it changes, and by
  `Board.OpenROV.UART` once a second with its liveness fields, see the moduledoc): `up`, `reason`
  and any of the boards' `Neptunus.Vehicle.Board.link_details/0`.
  """
  @spec link(String.t(), %{
          required(:up) => boolean(),
          required(:reason) => String.t(),
          optional(atom()) => term()
        }) :: :ok
  def link(id, %{up: up, reason: reason} = link) when is_boolean(up) and is_binary(reason),
    do: GenServer.cast(via(id), {:link, link})

  @doc """
  Reports the state of one of the vehicle's other parts, carried in every payload under its
  name until the next report: `:recording` (`Neptunus.Vehicle.Recorder`: `%{on, error}`) and
  `:camera` (`Neptunus.Vehicle.Camera`: `%{running, fps, error}`).
  """
  @spec report(String.t(), :recording | :camera, map()) :: :ok
  def report(id, part, status) when part in [:recording, :camera] and is_map(status),
    do: GenServer.cast(via(id), {:report, part, status})

  @doc "The latest telemetry payload, or nil before the first board sample."
  @spec latest(String.t()) :: map() | nil
  def latest(id), do: GenServer.call(via(id), :latest)

  defp via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    hz = Keyword.get(opts, :telemetry_hz, @default_hz)

    state = %State{
      id: id,
      topic: topic(id),
      periodic: Periodic.new(hz),
      pace: %{
        slice: Keyword.get(opts, :fanout_slice, @default_fanout_slice),
        gap_ms: Keyword.get(opts, :fanout_gap_ms, @default_fanout_gap_ms),
        spread_ms: div(500, hz)
      },
      command: %{surge: 0.0, heave: 0.0, yaw: 0.0},
      thrusters: Allocation.with_us(Allocation.neutral()),
      autopilot: @no_autopilot
    }

    Periodic.arm(state.periodic, :tick)
    {:ok, state, {:continue, :link}}
  end

  # The board starts before us and announces changes with link/2; read where it stands now.
  @impl true
  def handle_continue(:link, state) do
    link =
      try do
        Map.take(Board.link_status(state.id), link_keys())
      catch
        :exit, _ -> %{up: false, reason: "board not running"}
      end

    {:noreply, %{state | link: link}}
  end

  @impl true
  def handle_cast({:sample, sample}, state), do: {:noreply, %{state | sample: sample}}

  def handle_cast({:link, link}, state),
    do: {:noreply, %{state | link: Map.take(link, link_keys())}}

  def handle_cast({:report, part, status}, state),
    do: {:noreply, %{state | reports: Map.put(state.reports, part, status)}}

  def handle_cast({:control, c}, state) do
    {:noreply,
     %{
       state
       | command: c.command,
         thrusters: Allocation.with_us(c.thrusters),
         control: c.control,
         autopilot: c.autopilot,
         axes: Map.get(c, :axes, state.axes)
     }}
  end

  @impl true
  def handle_call(:latest, _from, state), do: {:reply, payload(state), state}

  @impl true
  def handle_info({PubSub, :slice, _, _, _, _} = slice, state) do
    PubSub.deliver_slice(slice)
    {:noreply, state}
  end

  def handle_info(:tick, state) do
    case payload(state) do
      nil -> :ok
      payload -> PubSub.broadcast_paced(state.topic, "telemetry", payload, state.pace)
    end

    # one broadcast per tick; ticks missed during a stall are skipped, not replayed
    {_due, periodic} = Periodic.advance(state.periodic, Neptunus.Clock.monotonic_native())
    Periodic.arm(periodic, :tick)
    {:noreply, %{state | periodic: periodic}}
  end

  defp payload(%State{sample: nil}), do: nil

  defp payload(%State{sample: sample} = state) do
    %{
      t: sample.t,
      sent_at: Neptunus.Clock.wall_us() / 1000,
      measurement: sample.measurement,
      measurement_state: Map.get(sample, :measurement_state, @initialising),
      estimate: Map.get(sample, :estimate, @no_estimate),
      wild_points:
        Map.get_lazy(sample, :wild_points, &Neptunus.Navigation.WildPoints.new_counts/0),
      position: Map.get(sample, :position, @no_position),
      sim: sample.sim,
      command: state.command,
      thrusters: state.thrusters,
      control: state.control,
      autopilot: state.autopilot,
      axes: state.axes,
      link: state.link
    }
    |> Map.merge(state.reports)
  end

  # what telemetry's `link` carries: the state and the boards' details
  defp link_keys, do: [:up, :reason | Board.link_details()]
end
