defmodule Neptunus.Vehicle.Board.OpenROV.SITL.Device do
  @moduledoc """
  The simulated OpenROV board of a SITL vehicle: owns a `Neptunus.Sim` and the firmware
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware`, which decides every byte and timing), and speaks
  on the master end of a pseudo-terminal pair created by the port program (`neptunus_uart pty
  LINK`, `Neptunus.Vehicle.Board.SerialPort.open_pty/2`), whose slave end is symlinked at
  `link` for `Neptunus.Vehicle.Board.OpenROV.UART` to open.

  It steps the simulation at `hz` (default `Neptunus.Sim.default_hz/0`, 100 Hz) on absolute deadlines
  (`Neptunus.Periodic`, at most #{20} catch-up steps per tick); at each step it gives the
  firmware the simulator's reading, runs the firmware's loop up to now, sends what it wrote and
  drives the simulator with the thrusters the firmware's ESC pulses give. Received bytes go to
  the firmware at the time they were read from the pty (the port program stamps each read,
  `NEPTUNUS_UART_RX_STAMPS`), and each step first takes what has arrived: a busy machine that
  runs this process late does not pile up in the board's 64-byte receive buffer what a real
  board would have read in between (it drops what overflows: `rx_dropped`). Each tick also
  publishes the true pose and the firmware's lights, laser and tilt for the simulated camera
  (`Neptunus.Camera.Pose`).

  `reset/1` reboots the board (as a USB Arduino that resets) without touching the simulated
  vehicle: the firmware starts again from millis 0 and the physics keep going. With
  `reset_on_open: true` it reboots the same way whenever the line is opened (the port program
  reports every open of the pty's slave end), as a USB Arduino does when its DTR line drops;
  with `:bootloader_ms` every reboot first runs a bootloader that loses what arrives (see
  `Neptunus.Vehicle.Board.OpenROV.SITL.Firmware`). If the port program exits, this process stops and
  is restarted with a new pair at the same link path: to the board link that is a hangup
  followed by a board that comes back.
  """
  use GenServer

  alias Neptunus.{Periodic, Sim}
  alias Neptunus.Camera.Pose
  alias Neptunus.Vehicle.Board.SerialPort
  alias Neptunus.Vehicle.Board.OpenROV.SITL.Firmware

  @max_catch_up 20
  @open_timeout 5_000

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            port: port(),
            pty: String.t(),
            sim: Neptunus.Sim.t(),
            firmware: Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.t(),
            periodic: Neptunus.Periodic.t(),
            skipped_steps: non_neg_integer(),
            rx_dropped: non_neg_integer(),
            reset_on_open: boolean(),
            rx_stamp_ms: integer() | nil,
            opens: non_neg_integer(),
            resets: non_neg_integer()
          }
    @enforce_keys [:id, :port, :pty, :sim, :firmware, :periodic]
    defstruct [
      :id,
      :port,
      :pty,
      :sim,
      :firmware,
      :periodic,
      skipped_steps: 0,
      rx_dropped: 0,
      reset_on_open: false,
      rx_stamp_ms: nil,
      opens: 0,
      resets: 0
    ]
  end

  @firmware_opts [:firmware, :wiring, :deadman_ms, :arm_ms, :loop_ms, :stall_ms, :setup_ms] ++
                   [:bootloader_ms]

  @doc """
  Options: `:id` and `:link` (path for the pty's slave end) required; `:hz` (default
  `Neptunus.Sim.default_hz/0`); `:os_time_slice_ns` (the slice its port program asks for,
  `Neptunus.OS`); the firmware's
  (`Neptunus.Vehicle.Board.OpenROV.SITL.Firmware.new/2`): `:firmware` (`:openrov_25` default or
  `:openrov_30`), `:wiring` (`Neptunus.Vehicle.Board.OpenROV.Wiring`, default the thesis'),
  `:deadman_ms` (2000), `:arm_ms` (180 000), `:loop_ms` (10), `:stall_ms` (20), `:setup_ms` (20),
  `:bootloader_ms` (0); `:reset_on_open` (false: the board reboots whenever the line is opened);
  `:initial` and `:sim` (options of `Neptunus.Sim.new/1`, over the default `noise: true` —
  realistic sensors with wild points — and a fresh seed).
  """
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    id = Keyword.fetch!(opts, :id)
    GenServer.start_link(__MODULE__, opts, name: Neptunus.Fleet.via(__MODULE__, id))
  end

  @doc """
  The device's state: the simulation (truth), the firmware, the pty path, `rx_dropped` (bytes
  the board's receive buffer lost), `opens` (times the line was opened), `resets` (board
  resets by `reset/1` or, with `reset_on_open`, by an open).
  """
  @spec state(String.t()) :: State.t()
  def state(id), do: GenServer.call(Neptunus.Fleet.via(__MODULE__, id), :state)

  @doc """
  Reboots the simulated board (its millis back to 0, every firmware state lost, the boot
  output again) without touching the simulated vehicle, whose physics keep going.
  """
  @spec reset(String.t()) :: :ok
  def reset(id), do: GenServer.call(Neptunus.Fleet.via(__MODULE__, id), :reset)

  # Callbacks

  @impl true
  def init(opts) do
    id = Keyword.fetch!(opts, :id)
    link = Keyword.fetch!(opts, :link)
    hz = Keyword.get(opts, :hz, Sim.default_hz())
    # a bad firmware option stops the device here with a clear error, before any pty exists
    firmware = Firmware.new(Neptunus.Clock.monotonic_ms(), Keyword.take(opts, @firmware_opts))

    File.mkdir_p!(Path.dirname(link))

    port_opts = [rx_stamps: true, env: Neptunus.OS.port_env(opts[:os_time_slice_ns])]

    # Deliberately synchronous (a few ms): the board link starts after us and must find the
    # device, as a real board's device node exists before the server starts.
    with {:ok, port} <- SerialPort.open_pty(link, port_opts),
         {:ok, pty} <- SerialPort.await_open(port, @open_timeout) do
      # the board was powered before anyone opened its line, as a real one is: its boot
      # output waits in the pty, where the opener drops it (a new session's stale input)
      {firmware, boot} = Firmware.started(firmware, Neptunus.Clock.monotonic_ms())

      state = %State{
        id: id,
        port: port,
        pty: pty,
        sim: Sim.new(sim_opts(opts, hz)),
        firmware: firmware,
        periodic: Periodic.new(hz) |> tap(&Periodic.arm(&1, :tick)),
        reset_on_open: Keyword.get(opts, :reset_on_open, false) == true
      }

      {:ok, send_bytes(state, boot)}
    else
      {:error, why} -> {:stop, {:pty, why}}
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

  def handle_call(:reset, _from, state), do: {:reply, :ok, reboot(state)}

  # what the old firmware wrote up to now goes out first, then the new one boots
  defp reboot(state) do
    now = Neptunus.Clock.monotonic_ms()
    {firmware, out} = Firmware.tick(state.firmware, now)
    state = send_bytes(state, out)
    firmware = Firmware.reset(firmware, now)

    %{
      state
      | firmware: firmware,
        sim: Sim.command(state.sim, firmware.thrusters),
        resets: state.resets + 1
    }
  end

  @impl true
  def handle_info({port, {:data, _} = message}, %State{port: port} = state),
    do: {:noreply, line_event(SerialPort.decode(message), state)}

  def handle_info({port, {:exit_status, status}}, %State{port: port} = state) do
    {:stop, {:pty_exited, status}, state}
  end

  def handle_info(:tick, state) do
    # what the line brought before now is read before the loop runs past it
    state = take_line_frames(state)
    now_native = Neptunus.Clock.monotonic_native()
    {due, periodic} = Periodic.advance(state.periodic, now_native)
    steps = min(due, @max_catch_up)

    # the firmware reads the sensors as they are now, runs its loop up to now, and its ESC
    # pulses drive the simulator for the steps that follow
    firmware = Firmware.sense(state.firmware, Sim.sample(state.sim))

    {firmware, out} =
      Firmware.tick(firmware, System.convert_time_unit(now_native, :native, :millisecond))

    sim = state.sim |> Sim.command(firmware.thrusters) |> Sim.step(steps)
    Periodic.arm(periodic, :tick)
    # for the simulated camera, if one renders this vehicle (nothing built when none does)
    Pose.publish(state.id, sim.dyn, %{
      lights: firmware.lights,
      laser: firmware.laser,
      tilt: (firmware.tilt - 1500) / 500 * :math.pi() / 4
    })

    state = %{
      state
      | sim: sim,
        firmware: firmware,
        periodic: periodic,
        skipped_steps: state.skipped_steps + due - steps,
        rx_dropped: firmware.rx_dropped
    }

    {:noreply, send_bytes(state, out)}
  end

  # Bytes from the line at the time they were read (the stamp before them), an open of the
  # line (a USB Arduino resets on it: DTR); nothing else the program says matters here
  defp line_event({:read_at_ns, ns}, state), do: %{state | rx_stamp_ms: vm_ms(ns)}

  defp line_event({:read, bytes}, state) do
    now = Neptunus.Clock.monotonic_ms()
    at = min(state.rx_stamp_ms || now, now)
    {firmware, reply} = Firmware.receive(state.firmware, bytes, at)
    send_bytes(apply_firmware(%{state | rx_stamp_ms: nil}, firmware), reply)
  end

  defp line_event(:peer_opened, state) do
    state = %{state | opens: state.opens + 1}
    if state.reset_on_open, do: reboot(state), else: state
  end

  defp line_event(_other, state), do: state

  defp take_line_frames(%State{port: port} = state) do
    receive do
      {^port, {:data, _} = message} ->
        take_line_frames(line_event(SerialPort.decode(message), state))
    after
      0 -> state
    end
  end

  # A CLOCK_MONOTONIC time (ns, the port program's stamp) on the node's clock (ms): the VM's
  # monotonic time runs on the OS's monotonic clock, offset (and possibly slewed a little, so
  # the offset is taken now); nil (the bytes count as read now) where that is not
  # CLOCK_MONOTONIC
  defp vm_ms(os_ns) do
    source = :erlang.system_info(:os_monotonic_time_source)

    if Keyword.get(source, :clock_id) == :CLOCK_MONOTONIC do
      os_now_ns = System.convert_time_unit(Keyword.fetch!(source, :time), :native, :nanosecond)
      Neptunus.Clock.monotonic_ms() - div(os_now_ns - os_ns, 1_000_000)
    end
  end

  defp apply_firmware(state, firmware) do
    %{
      state
      | firmware: firmware,
        sim: Sim.command(state.sim, firmware.thrusters),
        rx_dropped: firmware.rx_dropped
    }
  end

  defp send_bytes(state, bytes) do
    if IO.iodata_length(bytes) > 0 do
      # the program queues what the pty does not take at once; never block here
      _ = SerialPort.write(state.port, bytes)
    end

    state
  end
end
