defmodule Neptunus.Vehicle.Board do
  @moduledoc """
  The board link of a vehicle: the behaviour every board implements, and the API the rest of
  the vehicle uses to talk to whichever board is configured.

  A board process is registered as `Neptunus.Fleet.via(Neptunus.Vehicle.Board, id)` whatever
  its implementation, and

    * declares what its vehicle can do (the `capabilities/1` callback, `t:capabilities/0`): the
      body-frame axes it can be commanded in, and where the demand becomes thruster
      commands;
    * accepts `go/2` — for a board whose allocation is ours (`:thesis`) thruster values in
      [-1, 1], physical sense: positive pushes the vehicle forward for port/starboard, down for
      vertical; for a vehicle that allocates itself (`:vehicle`) the body-frame demand
      (`Neptunus.Control.Demand`) — and `neutral/1`;
    * sends every sample it reads to the vehicle's navigation process with `sample/3`
      (which passes it to `Neptunus.Vehicle.Navigation.sample/2` unless the vehicle flies the
      run-mode simulator; navigation filters it and passes it on to telemetry and control);
    * drives the thrusters neutral when it (re)starts.

  Implementations, by configured board type (`module/1`):

    * `:simulated` — `Neptunus.Vehicle.Board.Simulated`, the built-in simulator;
    * `:uart` — `Neptunus.Vehicle.Board.OpenROV.UART`, a real board on a serial port (OpenROV
      protocol through the `neptunus_uart` port program);
    * `:sitl` — `Neptunus.Vehicle.Board.OpenROV.SITL`, the simulator behind a pseudo-terminal
      speaking the OpenROV protocol, driven through `Board.OpenROV.UART`;
    * `:mavlink` — `Neptunus.Vehicle.Board.MAVLink`, an ArduSub vehicle over MAVLink;
    * any module implementing this behaviour (`Neptunus.Vehicle.Board.Test` in tests).

  Optional callbacks: `keepalive/1` (boards that feed a deadman: `Vehicle.Control` calls
  `keepalive/1` once a second while it is healthy), `link_status/1` (boards with a link that
  can go down), and `lights/2`, `laser/2` (0..255) and `tilt/2` (camera tilt, rad in
  [−π/4, π/4]; `tilt_us/1` gives the servo pulse width) — boards without them ignore those
  commands; `command/3` (vehicles with their own arming, flight modes or autopilots: one
  entry point, `command/3` here refuses for the others); `vet/1`; `parse_spec/1` (a board
  that `NEPTUNUS_VEHICLES` names `type:SPEC` parses its spec: `parse/1`) and `settings/0`
  (the per-vehicle settings its vehicles take: `takes?/2`).

  **Samples** go to navigation through `sample/3`, which passes on only the samples of the
  vehicle's current source: the board's, or — while `Vehicle.Control` runs in run mode
  `simulator` — those of the simulator standing in for it (`Vehicle.Control.sample_source/1`).
  """

  alias Neptunus.Allocation
  alias Neptunus.Control.Demand

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
  A real board (`Board.OpenROV.UART`) adds its other fields under `board` (e.g. `yaw`,
  `temperature`, `pressure`, `board_time`, see `Neptunus.Vehicle.Board.OpenROV.Protocol`).
  """
  @type sample :: %{
          required(:t) => float(),
          required(:measurement) => measurement(),
          required(:sim) => map() | nil,
          optional(:board) => map()
        }

  @typedoc """
  What a board's vehicle can do, declared by the board (`c:capabilities/1`):

    * `axes` — the body-frame axes the vehicle can be commanded in (`surge` forward, `sway` to
      starboard, `heave` down, `yaw` bow to starboard; `roll` and `pitch` where it can): the
      pilot's inputs offer these and no others;
    * `allocation` — where the demand becomes thruster commands: `:thesis` on our side (the
      three-thruster allocation, thesis eq. 9.3; `go/2` gets `%{port, vertical, starboard}`)
      or `:vehicle` on the vehicle (`go/2` gets the body-frame demand, e.g. ArduSub's own
      motor mixing);
    * `real` — a real vehicle (run mode simulator flies a simulator in its place) or the
      built-in simulator;
    * `autopilots` — whose depth and heading hold the `autopilot` command drives:
      Neptunus' own (`:neptunus`) or the vehicle's flight modes (`:vehicle`, through
      `command/3`).
  """
  @type capabilities :: %{
          axes: [Demand.axis()],
          allocation: :thesis | :vehicle,
          real: boolean(),
          autopilots: :neptunus | :vehicle
        }

  @typedoc "What `go/2` takes: see `t:capabilities/0`'s `allocation`."
  @type output :: Allocation.thrusters() | Demand.t()

  @typedoc """
  A command for the vehicle itself (`command/3`): arm or disarm, a flight mode by name, or
  depth and heading hold as `Neptunus.Control.Command` validates the `autopilot` payload.
  """
  @type vehicle_command ::
          {:arm, boolean()}
          | {:mode, String.t()}
          | {:autopilot, %{depth: term(), heading: term()}}

  @typedoc """
  A per-vehicle setting of `Neptunus.Config.Vehicles` that only some boards take, as each
  board declares (`c:settings/0`): a vehicle whose board takes it gets its default, one
  whose board does not refuses a configured value.

    * `:wiring`, `:firmware` — an OpenROV board's motor wiring and firmware profile
      (`NEPTUNUS_WIRING`, `NEPTUNUS_FIRMWARE`);
    * `:bootloader` — a simulated board that reboots into its bootloader when its line opens
      (`NEPTUNUS_SITL_BOOTLOADER`);
    * `:mavlink_ids`, `:disarm_delay` — our ids on a MAVLink link, the disarm after pilot
      loss (`NEPTUNUS_MAVLINK_IDS`, `NEPTUNUS_MAVLINK_DISARM_DELAY`);
    * `:sim_sources` — the vehicle lives in the built-in simulator (`Neptunus.Sim`): the
      simulated camera and position sources (`sim`, `sim-dvl`, `sim-usbl`) are its by
      default, and only its.
  """
  @type setting ::
          :wiring | :firmware | :bootloader | :mavlink_ids | :disarm_delay | :sim_sources

  @doc "Starts the board for vehicle `opts[:id]`; must register under `via/1`."
  @callback start_link(opts :: keyword()) :: GenServer.on_start()

  @doc """
  What the vehicle configured with `opts` (the vehicle's options, as `start_link/1` gets them)
  can do. Pure: called before the board starts.
  """
  @callback capabilities(opts :: keyword()) :: capabilities()

  @doc """
  Commands the vehicle (asynchronous, never blocks): thruster values or the demand, as the
  board's `allocation` says.
  """
  @callback go(id :: String.t(), output()) :: :ok

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
  A command for the vehicle itself (`t:vehicle_command/0`; boards whose vehicle has its own
  arming, flight modes or autopilots: `Neptunus.Vehicle.Board.MAVLink`). Returns at once;
  `notify` is called with `:ok` or `{:error, reason}` when the outcome is known, or
  `{:error, reason}` at once for a command it does not take.
  """
  @callback command(
              id :: String.t(),
              vehicle_command(),
              notify :: (:ok | {:error, String.t()} -> term())
            ) :: :ok | {:error, String.t()}

  @doc """
  Whether the board's vehicle can fly a validated control command
  (`Neptunus.Control.Command.t()`): `Neptunus.Vehicle.Control` refuses it with the reason
  otherwise. Boards without `vet/1` fly every command.
  """
  @callback vet(command :: term()) :: :ok | {:error, String.t()}

  @doc """
  The keys of the details its `link_status/1` reports beyond `up` and `reason`, which
  telemetry carries under `link` (each one in the wire schema's `link_status`).
  """
  @callback link_details() :: [atom()]

  @doc """
  The options of a vehicle whose board `NEPTUNUS_VEHICLES` names `type:SPEC` (e.g.
  `uart:/dev/ttyO1@57600`), from SPEC: `{:ok, options}` (the vehicle's, as `start_link/1`
  and `capabilities/1` get them), or `{:error, expected, why}` — the spec's syntax and what
  is wrong with this one, which `Neptunus.Config.Vehicles` puts in its error. Pure, and
  never raises. A board named by its type alone (`simulated`) has no spec and no
  `parse_spec/1`.
  """
  @callback parse_spec(spec :: String.t()) ::
              {:ok, map()} | {:error, expected :: String.t(), why :: String.t()}

  @doc """
  The per-vehicle settings this board's vehicles take (`t:setting/0`); boards without
  `settings/0` take none of them.
  """
  @callback settings() :: [setting()]

  @optional_callbacks parse_spec: 1,
                      settings: 0,
                      link_details: 0,
                      keepalive: 1,
                      link_status: 1,
                      lights: 2,
                      laser: 2,
                      tilt: 2,
                      command: 3,
                      vet: 1

  # The boards, once: type => {module, how NEPTUNUS_VEHICLES names it (nil: by its type alone;
  # else `type:` and the syntax of its spec, which the module's parse_spec/1 parses)}
  @registry [
    simulated: {Neptunus.Vehicle.Board.Simulated, nil},
    sitl: {Neptunus.Vehicle.Board.OpenROV.SITL, nil},
    uart: {Neptunus.Vehicle.Board.OpenROV.UART, "uart:DEVICE[@BAUD]"},
    mavlink: {Neptunus.Vehicle.Board.MAVLink, "mavlink:…"}
  ]
  @boards Map.new(@registry, fn {type, {module, _spec}} -> {type, module} end)

  @doc """
  How `NEPTUNUS_VEHICLES` names each board, in order: the type alone (`simulated`) or the
  syntax of its spec (`uart:DEVICE[@BAUD]`).

      iex> Neptunus.Vehicle.Board.syntaxes()
      ["simulated", "sitl", "uart:DEVICE[@BAUD]", "mavlink:…"]
  """
  @spec syntaxes() :: [String.t()]
  def syntaxes, do: for({type, {_m, spec}} <- @registry, do: spec || Atom.to_string(type))

  @doc """
  The board type configured by `name` alone (a board without a spec), or `:error`.

      iex> Neptunus.Vehicle.Board.named("sitl")
      {:ok, :sitl}
      iex> Neptunus.Vehicle.Board.named("uart")
      :error
  """
  @spec named(String.t()) :: {:ok, atom()} | :error
  def named(name) do
    case Enum.find(@registry, fn {type, {_m, spec}} ->
           spec == nil and Atom.to_string(type) == name
         end) do
      {type, _} -> {:ok, type}
      nil -> :error
    end
  end

  @doc "The board types, in order."
  @spec types() :: [atom()]
  def types, do: Keyword.keys(@registry)

  @doc """
  Whether a vehicle of board `board` (a type of `module/1`) takes `setting` (its board's
  `c:settings/0`).

      iex> Neptunus.Vehicle.Board.takes?(:sitl, :wiring)
      true
      iex> Neptunus.Vehicle.Board.takes?(:mavlink, :wiring)
      false
  """
  @spec takes?(atom(), setting()) :: boolean()
  def takes?(board, setting) do
    module = module(board)

    Code.ensure_loaded?(module) and function_exported?(module, :settings, 0) and
      setting in module.settings()
  end

  @doc """
  Whether a vehicle of board `board` (a type of `module/1`) has commands of its own — its
  board implements `c:command/3`: its own arming, flight modes, autopilots (ArduSub) —;
  the others are armed while a pilot holds the helm.

      iex> Neptunus.Vehicle.Board.own_commands?(:mavlink)
      true
      iex> Neptunus.Vehicle.Board.own_commands?(:uart)
      false
  """
  @spec own_commands?(atom()) :: boolean()
  def own_commands?(board) do
    module = module(board)
    Code.ensure_loaded?(module) and function_exported?(module, :command, 3)
  end

  @doc """
  The board types whose vehicles take `setting`, in order.

      iex> Neptunus.Vehicle.Board.taking(:sim_sources)
      [:simulated, :sitl]
  """
  @spec taking(setting()) :: [atom()]
  def taking(setting), do: Enum.filter(types(), &takes?(&1, setting))

  @doc """
  The board of a vehicle as `NEPTUNUS_VEHICLES` names it: a type alone (`simulated`) or
  `type:SPEC`, the spec parsed by the board (`c:parse_spec/1`). `{:ok, %{board: type, ...}}`
  with the board's options, or `{:error, expected, why}`. Pure, and never raises.

      iex> Neptunus.Vehicle.Board.parse("uart:/dev/ttyO1@57600")
      {:ok, %{board: :uart, device: "/dev/ttyO1", baud: 57600}}
      iex> Neptunus.Vehicle.Board.parse("sitl")
      {:ok, %{board: :sitl}}
      iex> Neptunus.Vehicle.Board.parse("uart:ttyO1")
      {:error, "uart:DEVICE[@BAUD]", "the device must be an absolute path such as /dev/ttyO1"}
      iex> Neptunus.Vehicle.Board.parse("warp")
      {:error, "a known board", "one of simulated, sitl, uart:DEVICE[@BAUD], mavlink:…"}
  """
  @spec parse(String.t()) ::
          {:ok, %{required(:board) => atom(), optional(atom()) => term()}}
          | {:error, String.t(), String.t()}
  def parse(text) when is_binary(text) do
    with :error <- named(text),
         [prefix, spec] <- String.split(text, ":", parts: 2),
         {type, {module, syntax}} when syntax != nil <-
           Enum.find(@registry, fn {type, _} -> Atom.to_string(type) == prefix end) do
      with {:ok, options} <- module.parse_spec(spec), do: {:ok, Map.put(options, :board, type)}
    else
      {:ok, type} -> {:ok, %{board: type}}
      _ -> {:error, "a known board", "one of " <> Enum.join(syntaxes(), ", ")}
    end
  end

  @doc """
  The board link's details every board with a link reports with its state (`up`, `reason`)
  and telemetry carries under `link`: the union of the boards' `link_details/0` (see
  `Neptunus.Vehicle.Board.OpenROV.UART.link_status/1`,
  `Neptunus.Vehicle.Board.MAVLink.link_status/1` and docs/API.md).
  """
  @spec link_details() :: [atom()]
  def link_details do
    @boards
    |> Map.values()
    |> Enum.filter(&(Code.ensure_loaded?(&1) and function_exported?(&1, :link_details, 0)))
    |> Enum.flat_map(& &1.link_details())
    |> Enum.uniq()
  end

  @doc "The implementation module for a configured board type (or a module implementing this behaviour)."
  @spec module(atom()) :: module()
  def module(board) when is_map_key(@boards, board), do: Map.fetch!(@boards, board)
  def module(board) when is_atom(board) and board not in [nil, true, false], do: board

  @doc "Registered name of the board process of vehicle `id`."
  @spec via(String.t()) :: GenServer.name()
  def via(id), do: Neptunus.Fleet.via(__MODULE__, id)

  @doc """
  Commands the vehicle (asynchronous; never blocks the caller) with thruster values or the
  body-frame demand, as its board's `allocation` says (`t:capabilities/0`), through the
  board's `go/2` (a board started on its own, outside a vehicle, gets the same cast its
  `go/2` sends). Navigation is told the thruster values (a demand's three-thruster
  equivalent): they drive the estimator's prediction.
  """
  @spec go(String.t(), output()) :: :ok
  def go(id, output) do
    Neptunus.Vehicle.Navigation.command(id, thrusters(output))

    case board_module(id) do
      {:ok, module} -> module.go(id, output)
      :error -> GenServer.cast(via(id), {:go, output})
    end
  end

  @doc """
  The three-thruster values of an output: thruster values as they are, a demand through the
  thesis' allocation (its sway left out).

      iex> Neptunus.Vehicle.Board.thrusters(%{surge: 0.5, sway: 0.3, heave: -0.2, yaw: 0.25})
      %{port: 0.75, vertical: -0.2, starboard: 0.25}
  """
  @spec thrusters(output()) :: Allocation.thrusters()
  def thrusters(%{port: _, vertical: _, starboard: _} = thrusters), do: thrusters

  def thrusters(%{surge: _} = demand) do
    {motion, _sway} = Demand.to_motion(demand)
    Allocation.motion(motion, 1.0)
  end

  @doc """
  What the vehicle configured as board `board` (a type of `module/1`) with options `opts`
  can do (its board's `c:capabilities/1`).
  """
  @spec capabilities(atom(), keyword()) :: capabilities()
  def capabilities(board, opts), do: module(board).capabilities(opts)

  @doc """
  What vehicle `id` can do (`t:capabilities/0`), as its supervisor registered it at start,
  with the axes its board declared since (`declare_axes/2`) if it did; nil for a vehicle not
  running here.
  """
  @spec capabilities(String.t()) :: capabilities() | nil
  def capabilities(id) do
    case Registry.lookup(Neptunus.Fleet.Registry, {__MODULE__.Capabilities, id}) do
      [{_pid, capabilities}] ->
        case Registry.lookup(Neptunus.Fleet.Registry, {__MODULE__.Axes, id}) do
          [{_pid, axes}] -> %{capabilities | axes: axes}
          [] -> capabilities
        end

      [] ->
        nil
    end
  end

  @doc """
  Declares the axes vehicle `id` can be commanded in now — called by its board's process, for
  a vehicle that tells them only once the board runs (an ArduSub's frame,
  `Neptunus.Vehicle.Board.MAVLink`), at start and on every change. While that process lives,
  `capabilities/1` gives these axes (the ground station endpoint and the join snapshot read
  them there); `Neptunus.Vehicle.Control` is told (it refuses thrust in another axis and
  telemetry carries its `axes`, which the pages follow).
  """
  @spec declare_axes(String.t(), [Demand.axis()]) :: :ok
  def declare_axes(id, axes) when is_list(axes) do
    key = {__MODULE__.Axes, id}

    case Registry.register(Neptunus.Fleet.Registry, key, axes) do
      {:ok, _owner} ->
        :ok

      {:error, {:already_registered, _pid}} ->
        Registry.update_value(Neptunus.Fleet.Registry, key, fn _ -> axes end)
    end

    Neptunus.Vehicle.Control.axes(id, axes)
  end

  @doc """
  Registers `capabilities` as vehicle `id`'s for `capabilities/1`, under the calling process
  (the vehicle's supervisor): they go when it goes.
  """
  @spec register_capabilities(String.t(), capabilities()) :: :ok
  def register_capabilities(id, capabilities) do
    {:ok, _} =
      Registry.register(Neptunus.Fleet.Registry, {__MODULE__.Capabilities, id}, capabilities)

    :ok
  end

  @doc """
  The capabilities of the three-thruster vehicle of the thesis (surge, heave, yaw; allocation
  ours), a real one: boards other than the built-in simulator and ArduSub declare these.
  """
  @spec thesis_capabilities() :: capabilities()
  def thesis_capabilities,
    do: %{axes: [:surge, :heave, :yaw], allocation: :thesis, real: true, autopilots: :neptunus}

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
  A command for vehicle `id` itself (see the `command/3` callback): `:ok` once asked
  (`notify` gets the outcome), or `{:error, reason}` at once — a board without such commands
  has no arming (`{:arm, _}`: "this vehicle's board has no arming (only mavlink vehicles
  arm)") and no flight modes.
  """
  @spec command(String.t(), vehicle_command(), (:ok | {:error, String.t()} -> term())) ::
          :ok | {:error, String.t()}
  def command(id, command, notify) when is_function(notify, 1) do
    with {:ok, module} <- board_module(id),
         true <- function_exported?(module, :command, 3) do
      module.command(id, command, notify)
    else
      _ -> {:error, no_command(command)}
    end
  end

  defp no_command({:arm, _}), do: "this vehicle's board has no arming (only mavlink vehicles arm)"
  defp no_command({:mode, _}), do: "this vehicle's board has no flight modes"
  defp no_command({:autopilot, _}), do: "this vehicle's autopilots are Neptunus' own"

  @doc "Arms or disarms vehicle `id`: `command(id, {:arm, arm?}, notify)`."
  @spec arm(String.t(), boolean(), (:ok | {:error, String.t()} -> term())) ::
          :ok | {:error, String.t()}
  def arm(id, arm?, notify) when is_boolean(arm?), do: command(id, {:arm, arm?}, notify)

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

  @doc "Drives all thrusters neutral (a zero demand to a vehicle that allocates itself)."
  @spec neutral(String.t()) :: :ok
  def neutral(id) do
    case capabilities(id) do
      %{allocation: :vehicle} -> go(id, Demand.zero())
      _ -> go(id, Allocation.neutral())
    end
  end

  @doc """
  Tells vehicle `id`'s board that its control is alive (asynchronous). A board with a deadman
  (`Board.OpenROV.UART`) feeds it only while this keeps coming; boards without the optional
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
