defmodule Neptunus.Vehicle.Board.MAVLink do
  @moduledoc """
  The `mavlink` board: an ArduSub vehicle (BlueROV2 and the like) over MAVLink 2
  (`Neptunus.Protocol.MAVLink`), `NEPTUNUS_VEHICLES=sub=mavlink:udp:0.0.0.0:14550` (see
  `Neptunus.Config.Vehicles` and docs/MAVLINK.md).

  A process shell over `Neptunus.Vehicle.Board.MAVLink.Core`, which makes every decision
  (link state, arming, what to send when, samples); this process owns the link, decodes and
  encodes frames, keeps one timer for the core's next deadline and carries out its actions.

  ## Links

    * `{:udp, address, port}` — listens on `address:port`; sends to whoever sent the last
      datagram (a companion computer's router sends the vehicle's stream there);
    * `{:udpout, host, port}` — sends to `host:port` from an ephemeral local port and reads
      the answers there;
    * `{:tcp, host, port}` — connects (ArduPilot SITL listens on TCP 5760); reconnects
      `reconnect_ms` (1 s) after a failure or a close;
    * `{:serial, device, baud}` — the `neptunus_uart` port program
      (`Neptunus.Vehicle.Board.SerialPort`, as `Neptunus.Vehicle.Board.OpenROV.UART` uses it);
      reopened `reconnect_ms` after it exits.

  Bytes from the link go through one decoder; frames lost, garbage and unknown messages are
  counted in `link_status/1`.

  ## Around the board

    * `go/2` casts (the body-frame demand from `Neptunus.Vehicle.Control`) become
      MANUAL_CONTROL; control drives neutral on every stop, so every stop sends a neutral
      MANUAL_CONTROL at once.
    * The process subscribes to the vehicle's topic: `stopped` with a pilot-loss reason and
      `helm` (who pilots) drive the disarm after pilot loss (`Core.stopped/3`,
      `Core.pilot/2`).
    * Samples (attitude, depth, battery) go to navigation (`Board.sample/3`) on every
      ATTITUDE; the link's state and the vehicle's (`mavlink`: armed, mode, system status,
      servo outputs, frame, …) go to `Telemetry.link/2` on every change of the link or the
      frame and once a second; the axes the vehicle's frame gives are declared
      (`Board.declare_axes/2`) as the board starts and on every change; each
      change of the link is broadcast as event `link` on `"vehicle:<id>"`; STATUSTEXT and the
      vehicle's arming and mode changes are `log` entries (category `vehicle`) on
      `"log:<id>"` with their severity.
    * `arm/3` arms or disarms; lights (`MAV_CMD_DO_SET_SERVO` on servo 9) and camera tilt
      (`MAV_CMD_DO_MOUNT_CONTROL`); no laser.
  """
  use GenServer

  require Logger

  alias Neptunus.PubSub
  alias Neptunus.PubSub.Follow
  alias Neptunus.Protocol.MAVLink, as: Codec
  alias Neptunus.Vehicle.{Board, Telemetry}
  alias Neptunus.Vehicle.Board.MAVLink.Core
  alias Neptunus.Vehicle.Board.SerialPort

  @behaviour Board

  @typedoc """
  Where the vehicle is (`mavlink:LINK` in `NEPTUNUS_VEHICLES`, `parse_spec/1`):
  `{:udp, address, port}` (listen on a local address), `{:udpout, host, port}` (send to the
  vehicle), `{:tcp, host, port}` (connect to it) or `{:serial, device, baud}` (through the
  `neptunus_uart` port program).
  """
  @type link ::
          {:udp, :inet.ip_address(), :inet.port_number()}
          | {:udpout | :tcp, String.t(), 1..65_535}
          | {:serial, String.t(), pos_integer()}

  defmodule State do
    @moduledoc false
    @type t :: %__MODULE__{
            id: String.t(),
            topic: String.t(),
            follow: Neptunus.PubSub.Follow.t(),
            link: Neptunus.Vehicle.Board.MAVLink.link(),
            core: Neptunus.Vehicle.Board.MAVLink.Core.t(),
            decoder: Neptunus.Protocol.MAVLink.Decoder.t(),
            seq: byte(),
            socket: port() | :gen_udp.socket() | :gen_tcp.socket() | nil,
            peer: {:inet.ip_address(), :inet.port_number()} | nil,
            timer: reference() | nil,
            reconnect_ms: pos_integer(),
            program: String.t(),
            transport: String.t(),
            counters: %{atom() => non_neg_integer()}
          }
    @enforce_keys [:id, :topic, :follow, :link, :core, :decoder, :program]
    defstruct [
      :id,
      :topic,
      :follow,
      :link,
      :core,
      :decoder,
      :socket,
      :peer,
      :timer,
      :program,
      seq: 0,
      reconnect_ms: 1_000,
      transport: "not opened yet",
      counters: %{sent: 0, send_errors: 0, received: 0, opens: 0}
    ]
  end

  @doc """
  Starts the board of vehicle `opts[:id]`, registered as `Board.via(id)`. Options: `:link`
  (required, see the moduledoc), `:system`, `:component` (ours, default 255/190),
  `:manual_period_ms`, `:link_timeout_ms`, `:command_timeout_ms`, `:disarm_delay` (s, as
  `NEPTUNUS_MAVLINK_DISARM_DELAY` configures it), `:lights_servo`, `:reconnect_ms`,
  `:program` (the port program for serial links).
  """
  @impl Board
  @spec start_link(keyword()) :: GenServer.on_start()
  def start_link(opts) do
    GenServer.start_link(__MODULE__, opts, name: Board.via(Keyword.fetch!(opts, :id)))
  end

  @doc """
  An ArduSub vehicle is commanded in surge, sway, heave and yaw (MANUAL_CONTROL `x`, `y`, `z`,
  `r`) at most and mixes its thrusters itself (its frame's motor factors); its depth and
  heading hold are its flight modes. Which of those axes this vehicle has, its frame tells:
  the running board declares them (`Board.declare_axes/2`, `Core.axes/1`) — surge, heave and
  yaw until the vehicle's `FRAME_CONFIG` is known, sway too for a frame that strafes.
  """
  @impl Board
  @spec capabilities(keyword()) :: Board.capabilities()
  def capabilities(_opts),
    do: %{
      axes: [:surge, :sway, :heave, :yaw],
      allocation: :vehicle,
      real: true,
      autopilots: :vehicle
    }

  @doc """
  The vehicle's link from the spec of `mavlink:LINK` (`t:link/0`): `udp:ADDRESS:PORT`,
  `udpout:HOST:PORT`, `tcp:HOST:PORT` or `serial:DEVICE[@BAUD]`.

      iex> Neptunus.Vehicle.Board.MAVLink.parse_spec("udp:0.0.0.0:14550")
      {:ok, %{link: {:udp, {0, 0, 0, 0}, 14550}}}
      iex> {:error, _expected, why} = Neptunus.Vehicle.Board.MAVLink.parse_spec("udp:myhost:1")
      iex> why
      "udp listens on a local IP address such as 0.0.0.0"
  """
  @impl Board
  @spec parse_spec(String.t()) :: {:ok, %{link: link()}} | {:error, String.t(), String.t()}
  def parse_spec(spec) do
    case link(spec) do
      {:ok, link} ->
        {:ok, %{link: link}}

      {:error, why} ->
        {:error,
         "mavlink:udp:ADDRESS:PORT, mavlink:udpout:HOST:PORT, mavlink:tcp:HOST:PORT or " <>
           "mavlink:serial:DEVICE[@BAUD]", why}
    end
  end

  defp link("serial:" <> line) do
    with {:ok, device, baud} <- SerialPort.parse_line(line), do: {:ok, {:serial, device, baud}}
  end

  defp link("udp:" <> address_port) do
    with {:ok, host, port} <- Neptunus.Config.host_port(address_port) do
      case :inet.parse_address(String.to_charlist(host)) do
        {:ok, address} -> {:ok, {:udp, address, port}}
        {:error, _} -> {:error, "udp listens on a local IP address such as 0.0.0.0"}
      end
    end
  end

  defp link("udpout:" <> host_port) do
    with {:ok, host, port} <- Neptunus.Config.host_port(host_port),
         do: {:ok, {:udpout, host, port}}
  end

  defp link("tcp:" <> host_port) do
    with {:ok, host, port} <- Neptunus.Config.host_port(host_port), do: {:ok, {:tcp, host, port}}
  end

  defp link(_), do: {:error, "the link must be udp, udpout, tcp or serial"}

  @doc "Our ids on its link and the disarm after pilot loss (`NEPTUNUS_MAVLINK_*`)."
  @impl Board
  @spec settings() :: [Board.setting()]
  def settings, do: [:mavlink_ids, :disarm_delay]

  @doc "The details `link_status/1` reports (telemetry's `link`): the round trip and the vehicle."
  @impl Board
  @spec link_details() :: [atom()]
  def link_details, do: [:rtt_ms, :mavlink]

  @doc "The body-frame demand (`Neptunus.Control.Demand`): MANUAL_CONTROL (`Core.go/3`)."
  @impl Board
  @spec go(String.t(), Neptunus.Control.Demand.t()) :: :ok
  def go(id, demand), do: GenServer.cast(Board.via(id), {:go, demand})

  @doc """
  The vehicle's own commands: `{:arm, boolean}` (`arm/3`), `{:mode, name}` (`set_mode/3`),
  `{:autopilot, setpoints}` (validated setpoints, `Core.autopilot/4`).
  """
  @impl Board
  @spec command(String.t(), Board.vehicle_command(), (:ok | {:error, String.t()} -> term())) ::
          :ok
  def command(id, {:arm, arm?}, notify), do: arm(id, arm?, notify)
  def command(id, {:mode, mode}, notify), do: set_mode(id, mode, notify)

  def command(id, {:autopilot, setpoints}, notify) when is_function(notify, 1),
    do: GenServer.call(Board.via(id), {:autopilot, setpoints, notify})

  @doc """
  The link's state: `%{up, reason, rtt_ms, mavlink: %{armed, mode, system_status, target,
  servo_us, control, disarm_pending, pilot_gain}, transport, counters, frames}` (`frames`: the
  decoder's counters, with `lost` frames from the vehicle's sequence numbers).
  """
  @impl Board
  @spec link_status(String.t()) :: map()
  def link_status(id), do: GenServer.call(Board.via(id), :link_status)

  @doc "Lights 0..255 (`MAV_CMD_DO_SET_SERVO` on the lights' output, 1100..1900 µs)."
  @impl Board
  @spec lights(String.t(), 0..255) :: :ok
  def lights(id, n), do: GenServer.cast(Board.via(id), {:lights, n})

  @doc "Camera tilt, rad (`MAV_CMD_DO_MOUNT_CONTROL`, pitch in degrees)."
  @impl Board
  @spec tilt(String.t(), number()) :: :ok
  def tilt(id, rad), do: GenServer.cast(Board.via(id), {:tilt, rad})

  @doc """
  Arms (`true`) or disarms (`false`) the vehicle. `notify` is called (in the board's
  process) with `:ok` or `{:error, reason}` once the vehicle answered, refused or did not
  answer in time; for a refusal at once (link down, a command already waiting) it is called
  before this returns.
  """
  @spec arm(String.t(), boolean(), (:ok | {:error, String.t()} -> term())) :: :ok
  def arm(id, arm?, notify) when is_boolean(arm?) and is_function(notify, 1),
    do: GenServer.call(Board.via(id), {:arm, arm?, notify})

  @doc "Refuses the control commands an ArduSub vehicle cannot fly (`Core.vet/1`)."
  @impl Board
  @spec vet(term()) :: :ok | {:error, String.t()}
  def vet(command), do: Core.vet(command)

  @doc "Sets the vehicle's flight mode by name (`Core.modes/0`); `notify` as for `arm/3`."
  @spec set_mode(String.t(), String.t(), (:ok | {:error, String.t()} -> term())) :: :ok
  def set_mode(id, mode, notify) when is_binary(mode) and is_function(notify, 1),
    do: GenServer.call(Board.via(id), {:set_mode, mode, notify})

  # Callbacks

  @impl true
  def init(opts) do
    # the control path runs before the web fan-out (see Neptunus.Vehicle.Helm)
    Process.flag(:priority, :high)
    Process.flag(:trap_exit, true)
    id = Keyword.fetch!(opts, :id)

    state = %State{
      id: id,
      topic: Telemetry.topic(id),
      follow: Follow.new([Telemetry.topic(id)]),
      link: Keyword.fetch!(opts, :link),
      core: Core.new(now_ms(), core_options(opts)),
      decoder: Codec.new(),
      reconnect_ms: Keyword.get(opts, :reconnect_ms, 1_000),
      program: Keyword.get(opts, :program) || SerialPort.program()
    }

    # no sway until the vehicle's frame says it has it (Core.axes/1)
    :ok = Board.declare_axes(id, Core.axes(state.core))
    {_subscribed_or_waiting, follow} = Follow.subscribe(state.follow)
    send(self(), :report)
    {:ok, %{state | follow: follow}, {:continue, :open}}
  end

  @impl true
  def handle_continue(:open, state),
    do: {:noreply, state |> open() |> run(&Core.tick(&1, now_ms()))}

  @impl true
  def handle_call(:link_status, _from, state) do
    status =
      state.core
      |> Core.status()
      |> Map.merge(%{
        transport: state.transport,
        counters: state.counters,
        frames: frames(state)
      })

    {:reply, status, state}
  end

  def handle_call({:arm, arm?, notify}, _from, state) do
    {:reply, :ok, run(state, &Core.arm(&1, notify, arm?, now_ms()))}
  end

  def handle_call({:autopilot, setpoints, notify}, _from, state) do
    {:reply, :ok, run(state, &Core.autopilot(&1, notify, setpoints, now_ms()))}
  end

  def handle_call({:set_mode, mode, notify}, _from, state) do
    {:reply, :ok, run(state, &Core.set_mode(&1, notify, mode, now_ms()))}
  end

  @impl true
  def handle_cast({:go, demand}, state),
    do: {:noreply, run(state, &Core.go(&1, demand, now_ms()))}

  def handle_cast({:lights, n}, state), do: {:noreply, run(state, &Core.lights(&1, n))}
  def handle_cast({:tilt, rad}, state), do: {:noreply, run(state, &Core.tilt(&1, rad))}

  @impl true
  def handle_info(:tick, state) do
    {:noreply, run(%{state | timer: nil}, &Core.tick(&1, now_ms()))}
  end

  def handle_info(:report, state) do
    Process.send_after(self(), :report, 1_000)
    report(state)
    {:noreply, state}
  end

  # UDP
  def handle_info({:udp, socket, ip, port, data}, %State{socket: socket} = state) do
    peer = if match?({:udp, _, _}, state.link), do: {ip, port}, else: state.peer
    {:noreply, received(%{state | peer: peer}, data)}
  end

  # TCP
  def handle_info({:tcp, socket, data}, %State{socket: socket} = state),
    do: {:noreply, received(state, data)}

  def handle_info({:tcp_closed, socket}, %State{socket: socket} = state),
    do: {:noreply, closed(state, "the vehicle closed the connection")}

  def handle_info({:tcp_error, socket, why}, %State{socket: socket} = state),
    do: {:noreply, closed(state, "TCP error: #{inspect(why)}")}

  # serial: the port program's messages
  def handle_info({port, {kind, _} = message}, %State{socket: port} = state)
      when is_port(port) and kind in [:data, :exit_status],
      do: {:noreply, serial(SerialPort.decode(message), state)}

  # The serial port is linked to us (we trap exits): its program's exit comes as exit_status
  # (above) first. A port closed before that status reached the VM (a write to a program that
  # had just ended: `epipe`) sends only this exit: closed all the same, and reopened.
  def handle_info({:EXIT, port, reason}, %State{socket: port} = state) when is_port(port),
    do: {:noreply, closed(state, "the serial port program is gone (#{inspect(reason)})")}

  def handle_info({:EXIT, _port, _reason}, state), do: {:noreply, state}

  def handle_info(:reopen, %State{socket: nil} = state), do: {:noreply, open(state)}
  def handle_info(:reopen, state), do: {:noreply, state}

  # the vehicle's topic: stops and the helm (disarm after pilot loss)
  def handle_info({:pubsub, _topic, "stopped", %{reason: reason}}, state),
    do: {:noreply, %{state | core: Core.stopped(state.core, reason, now_ms())} |> arm_timer()}

  # the pilot is known by their connection's id (the rest of the helm's party may change)
  def handle_info({:pubsub, _topic, "helm", %{pilot: pilot}}, state) do
    pilot = if is_map(pilot), do: Map.get(pilot, :id, pilot), else: pilot
    {:noreply, %{state | core: Core.pilot(state.core, pilot)}}
  end

  def handle_info({:pubsub, _topic, _event, _payload}, state), do: {:noreply, state}

  # the PubSub scope restarted: subscribe again (Follow)
  def handle_info({:DOWN, _ref, :process, _pid, _reason} = msg, state), do: follow(state, msg)
  def handle_info({Follow, :retry, _} = msg, state), do: follow(state, msg)

  def handle_info(msg, state) do
    Logger.debug("mavlink board #{state.id} ignored #{inspect(msg)}")
    {:noreply, state}
  end

  @impl true
  def terminate(_reason, state) do
    # an orderly shutdown leaves the vehicle neutral
    _ = run(state, &Core.neutral(&1, now_ms()))
    :ok
  end

  # --- the link ------------------------------------------------------------------------

  defp open(%State{link: {:udp, address, port}} = state) do
    case :gen_udp.open(port, [:binary, active: true, ip: address, reuseaddr: true]) do
      {:ok, socket} -> opened(state, socket, "listening on UDP #{port}")
      {:error, why} -> failed(state, "cannot listen on UDP #{port}: #{inspect(why)}")
    end
  end

  defp open(%State{link: {:udpout, host, port}} = state) do
    with {:ok, ip} <- :inet.getaddr(String.to_charlist(host), :inet),
         {:ok, socket} <- :gen_udp.open(0, [:binary, active: true]) do
      %{opened(state, socket, "sending to UDP #{host}:#{port}") | peer: {ip, port}}
    else
      {:error, why} -> failed(state, "cannot send to UDP #{host}:#{port}: #{inspect(why)}")
    end
  end

  defp open(%State{link: {:tcp, host, port}} = state) do
    opts = [:binary, active: true, nodelay: true, send_timeout: 100, send_timeout_close: true]

    case :gen_tcp.connect(String.to_charlist(host), port, opts, 2_000) do
      {:ok, socket} -> opened(state, socket, "connected to TCP #{host}:#{port}")
      {:error, why} -> failed(state, "cannot connect to TCP #{host}:#{port}: #{inspect(why)}")
    end
  end

  defp open(%State{link: {:serial, device, baud}} = state) do
    case SerialPort.open_tty(device, baud, program: state.program) do
      {:ok, port} -> opened(state, port, "opening #{device}")
      {:error, why} -> failed(state, "cannot start the serial port program: #{why}")
    end
  end

  defp serial({:read, data}, state), do: received(state, data)
  defp serial({:open, _path}, state), do: %{state | transport: "serial open"}
  defp serial({:error, text}, state), do: %{state | transport: "serial: #{text}"}

  defp serial({:exit, n}, state),
    do: closed(state, "the serial port program exited (#{n}): #{state.transport}")

  defp serial(_other, state), do: state

  defp opened(state, socket, transport) do
    counters = Map.update!(state.counters, :opens, &(&1 + 1))
    %{state | socket: socket, transport: transport, counters: counters}
  end

  defp failed(state, why) do
    Logger.warning("mavlink board #{state.id}: #{why}")
    Process.send_after(self(), :reopen, state.reconnect_ms)
    %{state | socket: nil, transport: why}
  end

  defp closed(state, why) do
    close(state)
    failed(%{state | socket: nil, decoder: Codec.new()}, why)
  end

  defp close(%State{link: {:serial, _, _}, socket: port}) when is_port(port),
    do: SerialPort.close(port)

  defp close(%State{link: {:tcp, _, _}, socket: socket}) when socket != nil,
    do: :gen_tcp.close(socket)

  defp close(_state), do: :ok

  defp received(state, data) do
    {decoder, messages, _events} = Codec.decode(state.decoder, data)
    counters = Map.update!(state.counters, :received, &(&1 + length(messages)))
    state = %{state | decoder: decoder, counters: counters}
    t = now_ms()
    Enum.reduce(messages, state, fn m, state -> run(state, &Core.receive(&1, m, t)) end)
  end

  defp frames(state) do
    stats = Codec.stats(state.decoder)
    lost = state.decoder |> Codec.sources() |> Map.values() |> Enum.map(& &1.lost) |> Enum.sum()
    Map.put(stats, :lost, lost)
  end

  # --- running the core ----------------------------------------------------------------

  defp run(state, step) do
    {core, actions} = step.(state.core)
    frame? = core.frame != state.core.frame
    state = Enum.reduce(actions, %{state | core: core}, &act/2)
    # the vehicle's frame is news for telemetry at once (its axes follow it)
    if frame?, do: report(state)
    arm_timer(state)
  end

  defp arm_timer(state) do
    if state.timer, do: Process.cancel_timer(state.timer)
    ms = max(0, Core.due(state.core) - now_ms())
    %{state | timer: Process.send_after(self(), :tick, ms)}
  end

  defp act({:send, name, fields}, state) do
    header = %{system: state.core.system, component: state.core.component, seq: state.seq}

    case Codec.encode(name, fields, header) do
      {:ok, frame} ->
        state = %{state | seq: Codec.next_seq(state.seq)}
        write(state, frame)

      {:error, why} ->
        Logger.error("mavlink board #{state.id}: cannot encode #{name}: #{inspect(why)}")
        state
    end
  end

  defp act({:reply, notify, result}, state) when is_function(notify, 1) do
    notify.(result)
    state
  end

  defp act({:link, link}, state) do
    PubSub.broadcast(state.topic, "link", link)

    Logger.info(
      "vehicle #{state.id}: mavlink link #{if link.up, do: "up", else: "down"} (#{link.reason})"
    )

    report(state)
    state
  end

  defp act({:log, level, text, extra}, state) do
    PubSub.broadcast(
      Telemetry.log_topic(state.id),
      "log",
      Map.merge(extra, %{
        category: "vehicle",
        level: Atom.to_string(level),
        message: text,
        at: Neptunus.Clock.wall_ms()
      })
    )

    Logger.log(level, "vehicle #{state.id}: #{Neptunus.Log.safe(text)}")
    state
  end

  defp act({:axes, axes}, state) do
    :ok = Board.declare_axes(state.id, axes)
    state
  end

  defp act({:sample, sample}, state) do
    Board.sample(state.id, sample)
    state
  end

  defp write(%State{socket: nil} = state, _frame), do: count(state, :send_errors)

  defp write(%State{link: {kind, _, _}, peer: nil} = state, _frame) when kind in [:udp, :udpout],
    do: count(state, :send_errors)

  defp write(%State{link: {kind, _, _}, socket: socket, peer: {ip, port}} = state, frame)
       when kind in [:udp, :udpout] do
    case :gen_udp.send(socket, ip, port, frame) do
      :ok -> count(state, :sent)
      {:error, _} -> count(state, :send_errors)
    end
  end

  defp write(%State{link: {:tcp, _, _}, socket: socket} = state, frame) do
    case :gen_tcp.send(socket, frame) do
      :ok -> count(state, :sent)
      {:error, _} -> count(state, :send_errors)
    end
  end

  defp write(%State{link: {:serial, _, _}, socket: port} = state, frame) do
    case SerialPort.write(port, frame) do
      :ok -> count(state, :sent)
      {:error, _busy_or_closed} -> count(state, :send_errors)
    end
  end

  defp count(state, key), do: %{state | counters: Map.update!(state.counters, key, &(&1 + 1))}

  # the link's state for telemetry, with the frames received and lost (from the vehicle's
  # sequence numbers)
  defp report(state) do
    status = Core.status(state.core)
    frames = frames(state)
    received = state.counters.received
    loss = if received + frames.lost > 0, do: frames.lost / (received + frames.lost), else: 0.0

    mavlink =
      Map.merge(status.mavlink, %{
        frames_received: received,
        frames_lost: frames.lost,
        loss: Float.round(loss, 4)
      })

    Telemetry.link(state.id, %{status | mavlink: mavlink})
  end

  defp follow(state, msg) do
    {_event, follow} = Follow.handle(state.follow, msg)
    {:noreply, %{state | follow: follow}}
  end

  # the configured disarm delay is in seconds; the core's durations are in ms
  defp core_options(opts) do
    case Keyword.pop(opts, :disarm_delay) do
      {nil, opts} -> opts
      {s, opts} -> Keyword.put(opts, :disarm_delay_ms, round(s * 1000))
    end
  end

  defp now_ms, do: Neptunus.Clock.monotonic_ms()
end
