defmodule Neptunus.Vehicle.Navigation do
  @moduledoc """
  A vehicle's navigation: every board sample comes here first (`sample/2`), goes through the
  wild-point tests and the Kalman filter of `Neptunus.Estimator`, and goes on

    * to `Neptunus.Vehicle.Telemetry` (`Telemetry.sample/2`) as the same sample with its
      `measurement` filtered — each field the last accepted reading, wild points never passed
      on, nil while initialising — plus `measurement_state` (each field `"initialising"`,
      `"valid"` or `"stale"`), `estimate` (`%{depth, depth_rate, heading, yaw_rate}`, nil
      values while there is none) and `wild_points` (`%{total, by_field, by_reason,
      reacquired}`);
    * to `Neptunus.Vehicle.Control` (`Control.estimate/2`) as
      `%{t, depth, depth_rate, heading, yaw_rate, position, measurement_state: %{depth,
      heading}}` (states as atoms; depth and heading values nil while not estimated), so
      Control can say why an autopilot cannot engage and idle an autopilot whose measurement
      is initialising. `position` is the position filter's estimate
      (`Neptunus.Navigation.Position.estimate/2`: `valid`, `reason`, `north`, `east`,
      velocities, frame, epoch, shift), telemetry's `position` its status with the 1-σ
      ellipse and each source's state.

  **Position.** The position sources (`Neptunus.Vehicle.Position`: a DVL, an Underwater GPS,
  the simulated ones) report here (`position/4`), and so does an ArduSub board's own
  `LOCAL_POSITION_NED` (its `position` field, a fix in the `ardusub` frame); the heading and
  depth estimates go along to the position filter on every sample. A vehicle without sources
  has no position (`valid: false`, `reason: "no position source"`), even a simulated one:
  the simulator's truth is never navigation's.

  **Board resets.** `board_reset/2` (the board link calls it when its link (re)opens and when
  it sees the board reset) puts every measurement back to initialising and restarts the
  settle time (`Neptunus.Estimator.reset/1`), and tells Control at once; a board's uptime
  (`sample.board.board_time`) going backwards does the same from the samples themselves.
  See `Neptunus.Estimator` for when a measurement becomes valid again.

  The thruster commands come in through `command/2` (`Neptunus.Vehicle.Board.go/2` sends
  every command here too, and Control sends the simulator's in run mode simulator): they
  drive the filter's prediction.

  It sits right after the board in the vehicle's `:rest_for_one` tree and only casts to the
  processes after it (casts to registered names never fail, so it never waits on them); a
  crash restarts it with a fresh filter, and Telemetry, Control and the Helm after it.

  Options: `:id` (required); `:navigation` — options of `Neptunus.Estimator.new/1` (e.g.
  `vehicle: nil` for a model-free filter); `:position` — the vehicle's position sources (their
  names are shown as waiting until they report); `:position_filter` — options of
  `Neptunus.Navigation.Position.new/1`. The filter's vehicle model is by default the
  simulator's parameter set when the board simulates (`sim: [vehicle: …]`), else `neptunus`.
  """
  use GenServer

  require Logger

  alias Neptunus.Estimator
  alias Neptunus.Navigation.Position
  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  # the standard deviation of an ArduSub vehicle's own position (m): it does not say
  @ardusub_std 0.5

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            estimator: Neptunus.Estimator.t() | nil,
            estimator_opts: keyword(),
            position: Neptunus.Navigation.Position.t(),
            temperature: float() | nil,
            board_position_at: term(),
            ardusub_origin: Neptunus.Navigation.Geo.point() | nil,
            samples: non_neg_integer(),
            board_resets: non_neg_integer()
          }
    @enforce_keys [:id, :estimator_opts, :position]
    defstruct [
      :id,
      :estimator,
      :estimator_opts,
      :position,
      :temperature,
      :board_position_at,
      :ardusub_origin,
      samples: 0,
      board_resets: 0
    ]
  end

  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: via(Keyword.fetch!(opts, :id)))
  end

  @doc "Reports a board sample (called by the board; asynchronous)."
  @spec sample(String.t(), Board.sample()) :: :ok
  def sample(id, sample), do: GenServer.cast(via(id), {:sample, sample})

  @doc """
  The board behind vehicle `id` reset, or its link (re)opened (asynchronous; `reason` is
  logged): every measurement is initialising again until the board's readings agree.
  """
  @spec board_reset(String.t(), String.t()) :: :ok
  def board_reset(id, reason) when is_binary(reason),
    do: GenServer.cast(via(id), {:board_reset, reason})

  @doc """
  A position source's report (asynchronous; `Neptunus.Position.Source.report/4`), arrived
  at `at` (s, monotonic): see `Neptunus.Navigation.Position.report/4`.
  """
  @spec position(String.t(), atom(), Position.report(), float()) :: :ok
  def position(id, source, report, at),
    do: GenServer.cast(via(id), {:position, source, report, at})

  @doc """
  The vehicle's depth estimate (m, or nil) and the water temperature from its board (°C, or
  nil): what an Underwater GPS topside asks for.
  """
  @spec water(String.t()) :: {float() | nil, float() | nil}
  def water(id), do: GenServer.call(via(id), :water)

  @doc "Reports the thruster command sent to the board (asynchronous; see `Board.go/2`)."
  @spec command(String.t(), map()) :: :ok
  def command(id, thrusters), do: GenServer.cast(via(id), {:command, thrusters})

  @doc """
  The navigation state: the latest `estimate` (as sent to Control, position excepted),
  filtered `measurement`, `measurement_state` (atoms), `wild_points`, the number of
  `samples` taken, `board_resets` (seen in the samples or told by `board_reset/2`), and the
  thruster `command` the filter's model is driven by (nil for a model-free filter).
  """
  @spec status(String.t()) :: map()
  def status(id), do: GenServer.call(via(id), :status)

  defp via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  # Callbacks

  @impl true
  def init(opts) do
    sources =
      opts
      |> Keyword.get(:position, [])
      |> Neptunus.Vehicle.Position.sources()
      |> Enum.map(&elem(&1, 0))

    state = %State{
      id: Keyword.fetch!(opts, :id),
      estimator_opts: estimator_opts(opts),
      position: Position.new(Keyword.get(opts, :position_filter, []) ++ [sources: sources])
    }

    {:ok, state, {:continue, :estimator}}
  end

  @impl true
  def handle_continue(:estimator, state),
    do: {:noreply, %{state | estimator: Estimator.new(state.estimator_opts)}}

  @impl true
  def handle_cast({:sample, sample}, state) do
    before = state.estimator

    estimator =
      Estimator.update(
        before,
        Map.get(sample, :t),
        Map.get(sample, :measurement),
        board_time(sample)
      )

    resets =
      if board_reset?(before, estimator) do
        Logger.warning(
          "vehicle #{state.id}: the board's clock went back (a board reset): " <>
            "every measurement is initialising"
        )

        state.board_resets + 1
      else
        state.board_resets
      end

    estimate = Estimator.estimate(estimator)
    states = Estimator.states(estimator)
    now = now_s()
    state = %{state | estimator: estimator} |> board_position(sample, now)

    position =
      state.position
      |> Position.heading(now, estimate.heading, Estimator.std(estimator, :heading))
      |> Position.depth(estimate.depth)
      |> Position.tick(now)

    Telemetry.sample(
      state.id,
      Map.merge(sample, %{
        measurement: Estimator.measurement(estimator),
        measurement_state: Map.new(states, fn {k, v} -> {k, Atom.to_string(v)} end),
        estimate: Map.delete(estimate, :t),
        wild_points: Estimator.wild_points(estimator),
        position: status(state, position, now)
      })
    )

    Control.estimate(
      state.id,
      control_estimate(estimate, states, Position.estimate(position, now))
    )

    {:noreply,
     %{
       state
       | position: position,
         temperature: temperature(sample) || state.temperature,
         samples: state.samples + 1,
         board_resets: resets
     }}
  end

  def handle_cast({:position, source, report, at}, state),
    do: {:noreply, %{state | position: Position.report(state.position, source, report, at)}}

  def handle_cast({:command, thrusters}, state),
    do: {:noreply, %{state | estimator: Estimator.command(state.estimator, thrusters)}}

  def handle_cast({:board_reset, reason}, state) do
    Logger.info("vehicle #{state.id}: board reset (#{reason}): every measurement is initialising")
    estimator = Estimator.reset(state.estimator)
    estimate = Estimator.estimate(estimator)
    position = Position.estimate(state.position, now_s())
    Control.estimate(state.id, control_estimate(estimate, Estimator.states(estimator), position))
    {:noreply, %{state | estimator: estimator, board_resets: state.board_resets + 1}}
  end

  @impl true
  def handle_call(:water, _from, state) do
    depth = Estimator.estimate(state.estimator).depth
    {:reply, {depth, state.temperature}, state}
  end

  def handle_call(:status, _from, state) do
    reply = %{
      estimate: Estimator.estimate(state.estimator),
      measurement: Estimator.measurement(state.estimator),
      measurement_state: Estimator.states(state.estimator),
      wild_points: Estimator.wild_points(state.estimator),
      samples: state.samples,
      board_resets: state.board_resets,
      command: state.estimator.model && state.estimator.model.commands,
      position: Position.status(state.position, now_s())
    }

    {:reply, reply, state}
  end

  defp control_estimate(estimate, states, position) do
    Map.merge(estimate, %{
      position: position,
      measurement_state: Map.take(states, [:depth, :heading])
    })
  end

  defp board_time(%{board: %{board_time: bt}}), do: bt
  defp board_time(_sample), do: nil

  # the estimator saw the board's clock go back
  defp board_reset?(%Estimator{board_time: before}, %Estimator{board_time: now})
       when is_float(before) and is_float(now),
       do: now < before

  defp board_reset?(_before, _after), do: false

  defp estimator_opts(opts) do
    sim = Keyword.get(opts, :sim, [])

    vehicle =
      if Keyword.keyword?(sim), do: Keyword.get(sim, :vehicle, "neptunus"), else: "neptunus"

    Keyword.merge([vehicle: vehicle], Keyword.get(opts, :navigation, []))
  end

  # an ArduSub vehicle's own position (LOCAL_POSITION_NED), when it sends a new one, and the
  # geodetic origin of its frame where it has one
  defp board_position(state, %{board: %{position: %{x: x, y: y, time_boot_ms: at} = p}}, now)
       when is_number(x) and is_number(y) and at != state.board_position_at do
    fix = %{t: now, north: x, east: y, std: @ardusub_std, valid: true, frame: :ardusub}
    position = Position.report(state.position, :ardusub, {:fix, fix}, now)
    %{state | position: position, board_position_at: at, ardusub_origin: Map.get(p, :origin)}
  end

  defp board_position(state, _sample, _now), do: state

  # telemetry's position: the filter's status, and the geodetic origin of its frame where
  # one is known (an ArduSub vehicle's own frame, from its GLOBAL_POSITION_INT)
  defp status(state, position, now) do
    status = Position.status(position, now)
    origin = if status.frame == "ardusub", do: state.ardusub_origin
    Map.put(status, :origin, origin)
  end

  defp temperature(%{board: %{temperature: t}}) when is_number(t), do: t * 1.0
  defp temperature(_sample), do: nil

  defp now_s, do: Neptunus.Clock.monotonic_ms() / 1000
end
