defmodule Neptunus.Vehicle.Board.SITL.Device do
  @moduledoc """
  The simulated OpenROV board of a SITL vehicle: owns a `Neptunus.Sim` and the firmware
  (`Neptunus.Vehicle.Board.SITL.Firmware`), and speaks the OpenROV protocol on the master
  end of a pseudo-terminal pair created by the port program (`neptunus_uart pty LINK`), whose
  slave end is symlinked at `link` for `Neptunus.Vehicle.Board.UART` to open.

  It steps the simulation at `hz` (default config `:sim_hz`, 100 Hz) on absolute deadlines
  (`Neptunus.Periodic`, at most #{20} catch-up steps per tick, like the simulated board), sends a
  navigation-data line at `telemetry_hz` (default 50 Hz) and a board-status line every fifth
  of those, and applies commands as their bytes arrive.

  The pseudo-terminal is created in `init/1` and the process answers only once it exists, so
  the board link started after it finds the device. If the port program exits, this process
  stops and is restarted with a new pair at the same link path: to the board link that is a
  hangup followed by a board that comes back — as when a real board resets.
  """
  use GenServer

  alias Neptunus.{Periodic, Sim}
  alias Neptunus.Vehicle.Board.SITL.Firmware

  @max_catch_up 20
  @open_timeout 5_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            port: port(),
            pty: String.t(),
            sim: Neptunus.Sim.t(),
            firmware: Neptunus.Vehicle.Board.SITL.Firmware.t(),
            periodic: Neptunus.Periodic.t(),
            steps_per_line: pos_integer(),
            lines: non_neg_integer(),
            skipped_steps: non_neg_integer()
          }
    @enforce_keys [:id, :port, :pty, :sim, :firmware, :periodic, :steps_per_line]
    defstruct [
      :id,
      :port,
      :pty,
      :sim,
      :firmware,
      :periodic,
      :steps_per_line,
      lines: 0,
      skipped_steps: 0
    ]
  end

  @doc """
  Options: `:id` and `:link` (path for the pty's slave end) required; `:wiring`
  (`Neptunus.Wiring`, default the thesis'), `:hz`, `:telemetry_hz` (default 50),
  `:deadman_ms` (default 3000), `:initial` and `:sim` (options of `Neptunus.Sim.new/1`, over
  the default `noise: true` — realistic sensors with wild points — and a fresh seed).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Neptunus.Fleet.via(__MODULE__, id))
  end

  @doc "The device's state: the simulation (truth), the firmware, the pty path."
  @spec state(String.t()) :: State.t()
  def state(id), do: GenServer.call(Neptunus.Fleet.via(__MODULE__, id), :state)

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    link = Keyword.fetch!(opts, :link)
    hz = Keyword.get(opts, :hz, Application.get_env(:neptunus, :sim_hz, 100))
    telemetry_hz = min(Keyword.get(opts, :telemetry_hz, 50), hz)
    File.mkdir_p!(Path.dirname(link))

    port =
      Port.open({:spawn_executable, Neptunus.Vehicle.Board.UART.program()}, [
        :binary,
        {:packet, 2},
        :exit_status,
        :use_stdio,
        {:env, Neptunus.OS.port_env()},
        args: ["pty", link]
      ])

    # Deliberately synchronous (a few ms): the board link starts after us and must find the
    # device, as a real board's device node exists before the server starts.
    receive do
      {^port, {:data, "o" <> pty}} ->
        now = System.monotonic_time(:millisecond)

        {:ok,
         %State{
           id: id,
           port: port,
           pty: pty,
           sim: Sim.new(sim_opts(opts, hz)),
           firmware: Firmware.new(now, Keyword.take(opts, [:wiring, :deadman_ms])),
           periodic: Periodic.new(hz) |> tap(&Periodic.arm(&1, :tick)),
           steps_per_line: max(div(hz, telemetry_hz), 1)
         }}

      {^port, {:data, "e" <> why}} ->
        {:stop, {:pty, why}}

      {^port, {:exit_status, status}} ->
        {:stop, {:pty, "port program exited with status #{status}"}}
    after
      @open_timeout -> {:stop, {:pty, :timeout}}
    end
  end

  # Realistic sensors by default, as on the simulated board: their wild points travel over the
  # serial line and the board link's parser has to reject them.
  defp sim_opts(opts, hz) do
    [noise: true, seed: :erlang.unique_integer([:positive])]
    |> Keyword.merge(Keyword.take(opts, [:initial]))
    |> Keyword.merge(Keyword.get(opts, :sim, []))
    |> Keyword.put(:dt, 1.0 / hz)
  end

  @impl true
  def handle_call(:state, _from, state), do: {:reply, state, state}

  @impl true
  def handle_info({port, {:data, "r" <> bytes}}, %State{port: port} = state) do
    now = System.monotonic_time(:millisecond)
    {firmware, reply} = Firmware.receive(state.firmware, bytes, now)
    state = %{state | firmware: firmware, sim: Sim.command(state.sim, firmware.thrusters)}
    {:noreply, send_bytes(state, reply)}
  end

  def handle_info({port, {:data, _other}}, %State{port: port} = state), do: {:noreply, state}

  def handle_info({port, {:exit_status, status}}, %State{port: port} = state) do
    {:stop, {:pty_exited, status}, state}
  end

  def handle_info(:tick, state) do
    now = System.monotonic_time()
    {due, periodic} = Periodic.advance(state.periodic, now)
    steps = min(due, @max_catch_up)

    {firmware, alarm} =
      Firmware.tick(state.firmware, System.convert_time_unit(now, :native, :millisecond))

    before = state.sim.steps
    sim = state.sim |> Sim.command(firmware.thrusters) |> Sim.step(steps)
    Periodic.arm(periodic, :tick)

    state = %{
      state
      | sim: sim,
        firmware: firmware,
        periodic: periodic,
        skipped_steps: state.skipped_steps + due - steps
    }

    state = send_bytes(state, alarm)

    # one navdata line per `steps_per_line` steps, status every fifth line
    if div(sim.steps, state.steps_per_line) > div(before, state.steps_per_line) do
      sample = Sim.sample(sim)
      status = if rem(state.lines, 5) == 0, do: Firmware.shared_data(sample, firmware), else: ""
      line = Firmware.navdata(sample, firmware)
      {:noreply, send_bytes(%{state | lines: state.lines + 1}, [status, line])}
    else
      {:noreply, state}
    end
  end

  defp send_bytes(state, bytes) do
    if IO.iodata_length(bytes) > 0 do
      # the program queues what the pty does not take at once; never block here
      _ = :erlang.port_command(state.port, ["w", bytes], [:nosuspend])
    end

    state
  end
end
