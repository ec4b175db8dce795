defmodule Neptunus.Vehicle.Board do
  @moduledoc """
  The board link of a vehicle: the behaviour every board implements, and the API the rest of
  the vehicle uses to talk to whichever board is configured.

  A board process is registered as `Neptunus.Fleet.via(Neptunus.Vehicle.Board, id)` whatever
  its implementation, and

    * accepts `go/2` (thruster values in [-1, 1], physical sense: positive pushes the vehicle
      forward for port/starboard, down for vertical) and `neutral/1`;
    * sends every sample it reads to the vehicle's navigation process with `sample/3`
      (which passes it to `Neptunus.Vehicle.Navigation.sample/2` unless the vehicle flies the
      run-mode simulator; navigation filters it and passes it on to telemetry and control);
    * drives the thrusters neutral when it (re)starts.

  Implementations, by configured board type (`module/1`):

    * `:simulated` — `Neptunus.Vehicle.Board.Simulated`, the built-in simulator;
    * `:uart` — `Neptunus.Vehicle.Board.UART`, a real board on a serial port (OpenROV
      protocol through the `neptunus_uart` port program);
    * `:sitl` — `Neptunus.Vehicle.Board.SITL`, the simulator behind a pseudo-terminal speaking
      the OpenROV protocol, driven through `Board.UART`;
    * `:mavlink` — `Neptunus.Vehicle.Board.MAVLink`, an ArduSub vehicle over MAVLink;
    * any module implementing this behaviour (`Neptunus.Vehicle.Board.Test` in tests).

  Optional callbacks: `keepalive/1` (boards that feed a deadman: `Vehicle.Control` calls
  `keepalive/1` once a second while it is healthy), `link_status/1` (boards with a link that
  can go down), and `lights/2`, `laser/2` (0..255) and `tilt/2` (camera tilt, rad in
  [−π/4, π/4]; `tilt_us/1` gives the servo pulse width) — boards without them ignore those
  commands; `arm/3` (vehicles with their own arming; `arm/3` here refuses for the others).

  **Samples** go to navigation through `sample/3`, which passes on only the samples of the
  vehicle's current source: the board's, or — while `Vehicle.Control` runs in run mode
  `simulator` — those of the simulator standing in for it (`Vehicle.Control.sample_source/1`).
  """

  alias Neptunus.Allocation

  @typedoc "What a board measures (SI units, heading in [0, 2π))."
  @type measurement :: %{
          depth: float(),
          heading: float(),
          roll: float(),
          pitch: float(),
          voltage: float(),
          current: float()
        }

  @typedoc """
  A board sample: time (s, vehicle clock), measurements, and the simulator's truth if any.
  A real board (`Board.UART`) adds its other fields under `board` (e.g. `yaw`, `temperature`,
  `pressure`, `board_time`, see `Neptunus.Protocol.OpenROV`).
  """
  @type sample :: %{
          required(:t) => float(),
          required(:measurement) => measurement(),
          required(:sim) => map() | nil,
          optional(:board) => map()
        }

  @doc "Starts the board for vehicle `opts[:id]`; must register under `via/1`."
  @callback start_link(opts :: keyword()) :: GenServer.on_start()

  @doc "Vehicle `id`'s control is alive (called about once a second); see `keepalive/1`."
  @callback keepalive(id :: String.t()) :: :ok

  @doc "The link's state: `%{up: boolean, reason: String.t()}` and implementation details."
  @callback link_status(id :: String.t()) :: map()

  @doc "Sets the lights, 0..255 (asynchronous)."
  @callback lights(id :: String.t(), 0..255) :: :ok

  @doc "Sets the laser, 0..255 (asynchronous)."
  @callback laser(id :: String.t(), 0..255) :: :ok

  @doc "Tilts the camera to `rad` in [−π/4, π/4] (asynchronous)."
  @callback tilt(id :: String.t(), float()) :: :ok

  @doc """
  Arms (`true`) or disarms (`false`) the vehicle (boards whose vehicle has its own arming:
  `Neptunus.Vehicle.Board.MAVLink`). Returns at once; `notify` is called with `:ok` or
  `{:error, reason}` when the outcome is known.
  """
  @callback arm(id :: String.t(), boolean(), notify :: (:ok | {:error, String.t()} -> term())) ::
              :ok

  @doc """
  Whether the board's vehicle can fly a validated control command
  (`Neptunus.Control.Command.t()`): `Neptunus.Vehicle.Control` refuses it with the reason
  otherwise. Boards without `vet/1` fly every command.
  """
  @callback vet(command :: term()) :: :ok | {:error, String.t()}

  @optional_callbacks keepalive: 1, link_status: 1, lights: 2, laser: 2, tilt: 2, arm: 3, vet: 1

  @boards %{
    simulated: Neptunus.Vehicle.Board.Simulated,
    uart: Neptunus.Vehicle.Board.UART,
    sitl: Neptunus.Vehicle.Board.SITL,
    mavlink: Neptunus.Vehicle.Board.MAVLink
  }

  @doc """
  The board link's liveness details a board with a link reports with its state (`up`,
  `reason`) and telemetry carries under `link` (see `Neptunus.Vehicle.Board.UART.link_status/1`
  and docs/API.md).
  """
  @spec link_details() :: [atom()]
  def link_details do
    [
      :rtt_ms,
      :pong_age_ms,
      :board_uptime_ms,
      :board_deadman_armed,
      :firmware,
      :detected_firmware,
      :firmware_mismatch,
      :commands_sent,
      :commands_confirmed,
      :board_settings,
      :board_settings_pending,
      :board_settings_reason,
      :thrust_held,
      :mavlink
    ]
  end

  @doc "The implementation module for a configured board type (or a module implementing this behaviour)."
  @spec module(atom()) :: module()
  def module(board) when is_map_key(@boards, board), do: Map.fetch!(@boards, board)
  def module(board) when is_atom(board) and board not in [nil, true, false], do: board

  @doc "Registered name of the board process of vehicle `id`."
  @spec via(String.t()) :: GenServer.name()
  def via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  @doc """
  Commands the thrusters (asynchronous; never blocks the caller). Navigation is told the same
  command (`Neptunus.Vehicle.Navigation.command/2`): it drives the estimator's prediction.
  """
  @spec go(String.t(), Allocation.thrusters()) :: :ok
  def go(id, thrusters) do
    Neptunus.Vehicle.Navigation.command(id, thrusters)
    GenServer.cast(via(id), {:go, thrusters})
  end

  @doc """
  Reports a sample read by vehicle `id`'s board (`source` `:board`) or by the simulator that
  stands in for it in run mode simulator (`:simulator`) to navigation — if `source` is the
  vehicle's current sample source (`Neptunus.Vehicle.Control.sample_source/1`); otherwise
  it is dropped (the real board keeps reporting while the pilot flies the simulator).
  """
  @spec sample(String.t(), sample(), :board | :simulator) :: :ok
  def sample(id, sample, source \\ :board) do
    if Neptunus.Vehicle.Control.sample_source(id) == source,
      do: Neptunus.Vehicle.Navigation.sample(id, sample),
      else: :ok
  end

  @doc "Sets the lights of vehicle `id`'s board, 0..255 (ignored by boards without lights)."
  @spec lights(String.t(), 0..255) :: :ok
  def lights(id, n) when n in 0..255, do: optional(id, :lights, n)

  @doc "Sets the laser of vehicle `id`'s board, 0..255 (ignored by boards without one)."
  @spec laser(String.t(), 0..255) :: :ok
  def laser(id, n) when n in 0..255, do: optional(id, :laser, n)

  @doc "Tilts vehicle `id`'s camera to `rad` in [−π/4, π/4] (ignored by boards without one)."
  @spec tilt(String.t(), number()) :: :ok
  def tilt(id, rad) when is_number(rad), do: optional(id, :tilt, rad)

  @doc """
  The camera tilt servo's pulse width for `rad`: −π/4 … π/4 maps linearly onto 1000..2000 µs
  (1500 level), clamped.

      iex> Neptunus.Vehicle.Board.tilt_us(0.0)
      1500
      iex> Neptunus.Vehicle.Board.tilt_us(:math.pi() / 4)
      2000
      iex> Neptunus.Vehicle.Board.tilt_us(-:math.pi() / 8)
      1250
  """
  @spec tilt_us(number()) :: 1000..2000
  def tilt_us(rad) when is_number(rad) do
    x = (rad / (:math.pi() / 4)) |> max(-1.0) |> min(1.0)
    round(1500 + 500 * x)
  end

  defp optional(id, callback, value) do
    with {:ok, module} <- board_module(id),
         true <- function_exported?(module, callback, 2) do
      apply(module, callback, [id, value])
    end

    :ok
  end

  @doc "The configured board type of vehicle `id` (`:simulated`, `:uart`, …), nil if none."
  @spec type(String.t()) :: atom() | nil
  def type(id) do
    case Registry.lookup(Neptunus.Fleet.Registry, {Neptunus.Vehicle.Supervisor, id}) do
      [{_pid, board}] -> board
      [] -> nil
    end
  end

  @doc """
  Arms or disarms vehicle `id` (see the `arm/3` callback): `:ok` once asked (`notify` gets the
  outcome), or `{:error, reason}` at once for a board without arming.
  """
  @spec arm(String.t(), boolean(), (:ok | {:error, String.t()} -> term())) ::
          :ok | {:error, String.t()}
  def arm(id, arm?, notify) when is_boolean(arm?) and is_function(notify, 1) do
    with {:ok, module} <- board_module(id),
         true <- function_exported?(module, :arm, 3) do
      module.arm(id, arm?, notify)
    else
      _ -> {:error, "this vehicle's board has no arming (only mavlink vehicles arm)"}
    end
  end

  @doc "Whether vehicle `id`'s board can fly a validated control command (`vet/1` callback)."
  @spec vet(String.t(), term()) :: :ok | {:error, String.t()}
  def vet(id, command) do
    with {:ok, module} <- board_module(id),
         true <- function_exported?(module, :vet, 1) do
      module.vet(command)
    else
      _ -> :ok
    end
  end

  @doc "Drives all thrusters neutral."
  @spec neutral(String.t()) :: :ok
  def neutral(id), do: go(id, Allocation.neutral())

  @doc """
  Tells vehicle `id`'s board that its control is alive (asynchronous). A board with a deadman
  (`Board.UART`) feeds it only while this keeps coming; boards without the optional
  `keepalive/1` callback ignore it.
  """
  @spec keepalive(String.t()) :: :ok
  def keepalive(id) do
    with {:ok, module} <- board_module(id),
         true <- function_exported?(module, :keepalive, 1) do
      module.keepalive(id)
    end

    :ok
  end

  @doc """
  The board link's state, `%{up: boolean, reason: String.t(), ...}`; boards without a link
  (the built-in simulator) are always `%{up: true, reason: "no link"}`.
  """
  @spec link_status(String.t()) :: map()
  def link_status(id) do
    with {:ok, module} <- board_module(id),
         true <- function_exported?(module, :link_status, 1) do
      module.link_status(id)
    else
      _ -> %{up: true, reason: "no link"}
    end
  end

  # The board type is the value of the vehicle supervisor's registration.
  defp board_module(id) do
    case Registry.lookup(Neptunus.Fleet.Registry, {Neptunus.Vehicle.Supervisor, id}) do
      [{_pid, board}] -> {:ok, module(board)}
      [] -> :error
    end
  end
end
