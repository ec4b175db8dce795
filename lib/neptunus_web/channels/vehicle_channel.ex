defmodule NeptunusWeb.Channels.VehicleChannel do
  @moduledoc """
  Topic `vehicle:<id>`: one vehicle's telemetry, helm, presence and the pilot's commands.
  The channel decides nothing: it hands every command to the vehicle's
  `Neptunus.Vehicle.Helm` (which checks that the sender is the pilot and carries the
  command out) and relays the answers. Payloads and error reasons: `docs/API.md`.

  Join reply (state snapshot): `%{vehicle, telemetry, helm, pilot, control, camera, settings,
  session}` (`camera`: `%{codec, video, url}`, the video WebSocket's path and the MJPEG
  stream's, see `Neptunus.Vehicle.Camera.info/1`, or nil; `settings`: the vehicle's view
  settings, `Neptunus.Vehicle.ViewSettings`),
  followed by `presence_state`. Joining never depends on control: observers join like
  pilots, and being refused control is an event, never a closed channel.

  The client events (commands) and server events, their payloads and replies, and who may
  send each: the wire schema, `NeptunusWeb.WireSchema` (docs/API.md); a command added here is
  added there. Commands go through the vehicle's `Neptunus.Vehicle.Helm` (pilot only) to
  `Neptunus.Vehicle.Control.command/3` (the settings), `Neptunus.Sim.Live` (the simulator) or
  the board (`arm`, `disarm` and, on a vehicle whose autopilots are its own — the board's
  capabilities say `autopilots: :vehicle`, e.g. ArduSub's flight modes — `autopilot`:
  `Neptunus.Vehicle.Board.command/3`, whose late answer comes as `vehicle_answer`);
  the tuning and the camera rotation are for the user who pilots or the main station.

  A vehicle on another node of the fleet is joined the same way (its snapshot is made there,
  its helm, control and settings called there); this node says `unreachable` and `reachable`
  when that node is cut off and back (`Neptunus.Fleet.Directory`).

  Presence: keyed by user name, one meta per connection:
  `%{name, role, since, pilot, conn, node, online_at}`; `pilot` is updated on every grant and
  loss of control. When the presence server restarts (`:presence_restarted`), the channel
  tracks again and pushes `presence_state` anew: the client's presences are right again.
  """
  @behaviour NeptunusWeb.Channel

  alias Neptunus.Fleet
  alias Neptunus.Vehicle.{Board, Control, Helm, Telemetry, ViewSettings}
  alias NeptunusWeb.{Auth, Channel, Presence}

  @control_events ~w(set_control_mode set_gain set_lights set_laser set_tilt autopilot set_run_mode
                     mission)
  # how long an arm/disarm/autopilot reply waits for a mavlink vehicle's answer (a pilot's
  # heartbeats wait behind it: well under the deadman)
  @vehicle_answer_ms 200

  @impl true
  def join("vehicle:" <> id, _payload, socket) do
    # a vehicle on another node of the fleet is joined the same way: its state comes from
    # its node, its commands go to its helm there (Neptunus.Vehicle.Helm), its broadcasts
    # through this node's relay (Neptunus.PubSub)
    where =
      if Fleet.local?(id) do
        {:ok, node()}
      else
        case Fleet.locate(id) do
          {:ok, node, _helm} -> {:ok, node}
          {:error, :unreachable} -> {:error, "vehicle unreachable: #{id}"}
          {:error, :not_found} -> {:error, "unknown vehicle: #{id}"}
        end
      end

    with {:ok, node} <- where,
         {:ok, state} <- vehicle_state(node, id) do
      socket =
        Channel.assign(socket,
          vehicle_id: id,
          autopilots: state.vehicle[:autopilots],
          since_wall_ms: Neptunus.Clock.wall_ms()
        )

      socket = track(socket, false)
      Channel.send_self(socket, :after_join)
      {:ok, Map.put(state, :session, session(socket)), socket}
    else
      {:error, reason} -> {:error, %{reason: reason}}
    end
  end

  @impl true
  def handle_in("thrust", payload, socket) do
    socket |> id() |> Helm.thrust(party(socket), payload) |> reply(socket)
  end

  def handle_in("stop", payload, socket) do
    reason =
      case payload do
        %{"reason" => reason} when is_binary(reason) and byte_size(reason) in 1..100 -> reason
        _ -> "pilot_stop"
      end

    socket |> id() |> Helm.stop(party(socket), reason) |> reply(socket)
  end

  def handle_in("heartbeat", _payload, socket) do
    socket |> id() |> Helm.heartbeat(party(socket)) |> reply(socket)
  end

  # The server's wall clock, the one of telemetry's sent_at, for anyone joined: a page
  # estimates its offset from the round trip and so tells how old the telemetry it gets is.
  def handle_in("clock", _payload, socket) do
    {:reply, {:ok, %{now: Neptunus.Clock.wall_us() / 1000}}, socket}
  end

  def handle_in("request_control", _payload, socket) do
    socket |> id() |> Helm.request_control(party(socket)) |> reply(socket)
  end

  def handle_in("answer_request", %{"accept" => accept}, socket) when is_boolean(accept) do
    socket |> id() |> Helm.answer_request(party(socket), accept) |> reply(socket)
  end

  def handle_in("answer_request", _payload, socket) do
    {:reply, {:error, %{reason: "accept must be true or false"}}, socket}
  end

  def handle_in("take_control", _payload, socket) do
    socket |> id() |> Helm.take_control(party(socket)) |> reply(socket)
  end

  def handle_in("release_control", _payload, socket) do
    socket |> id() |> Helm.release_control(party(socket)) |> reply(socket)
  end

  # Arming and, on a vehicle whose autopilots are its own (its board's capabilities, e.g.
  # ArduSub's flight modes), the autopilots: commands for the vehicle itself
  # (Neptunus.Vehicle.Board.command/3), pilot only, through the helm. The vehicle's answer is
  # awaited at most @vehicle_answer_ms (the connection's heartbeats wait meanwhile): the reply
  # carries it, or says `pending` and the answer follows as event `vehicle_answer`.
  def handle_in(event, _payload, socket) when event in ["arm", "disarm"] do
    board_request(socket, event, &Board.command(&1, {:arm, event == "arm"}, &2))
  end

  # a position source's device (a DVL's reset or gyro calibration): pilot only; the answer may
  # take seconds (a calibration up to 15), so it follows as `vehicle_answer`
  def handle_in("position_source", payload, socket) do
    board_request(socket, "position_source", &Neptunus.Vehicle.Position.request(&1, payload, &2))
  end

  def handle_in("autopilot", payload, socket)
      when socket.assigns.autopilots == "vehicle" and is_map(payload) do
    with {:ok, {:autopilot, _} = command} <-
           Neptunus.Control.Command.validate("autopilot", payload) do
      board_request(socket, "autopilot", &Board.command(&1, command, &2))
    else
      {:error, reason} -> reply({:error, reason}, socket)
    end
  end

  # Control commands (Neptunus.Vehicle.Control.command/3): pilot only, through the helm like
  # every command, so no handover can come between the check and the command.
  def handle_in(event, payload, socket) when event in @control_events do
    id = id(socket)

    id
    |> Helm.command(party(socket), :none, fn -> Control.command(id, event, payload) end)
    |> reply(socket)
  end

  # Autopilot tuning (Neptunus.Vehicle.Control.tune/2, step_response/2): the user who pilots
  # or the main station. The work — a headless simulation, a settings write — runs here, not
  # in the helm or control.
  def handle_in(event, payload, socket) when event in ["set_tuning", "step_response"] do
    id = id(socket)

    with :ok <- may_tune(id, socket, "tuning") do
      case event do
        "set_tuning" -> on_vehicle(id, Control, :tune, [id, payload])
        "step_response" -> on_vehicle(id, Control, :step_response, [id, payload])
      end
    end
    |> reply(socket)
  end

  # The camera image rotation, a vehicle setting every page applies (Neptunus.Vehicle.ViewSettings):
  # the user who pilots or the main station.
  def handle_in("set_camera_rotation", payload, socket) do
    id = id(socket)

    with :ok <- may_tune(id, socket, "the camera rotation") do
      on_vehicle(id, ViewSettings, :set_camera_rotation, [id, payload])
    end
    |> reply(socket)
  end

  def handle_in("get_tuning", _payload, socket) do
    id = id(socket)

    case on_vehicle(id, Control, :tuning, [id]) do
      {:error, reason} -> {:error, reason}
      tuning -> {:ok, tuning}
    end
    |> reply(socket)
  end

  # Simulator controls `sim_reset`, `sim_set` (Neptunus.Sim.Live): pilot only, through the
  # helm like every command; refused on a board that is not the built-in simulator.
  def handle_in(event, payload, socket) when event in ["sim_reset", "sim_set"] do
    id = id(socket)

    id
    |> Helm.command(party(socket), :none, fn -> Neptunus.Sim.Live.command(id, event, payload) end)
    |> reply(socket)
  end

  # A snapshot of the camera (Neptunus.Camera.Snapshots): anyone watching. The picture is
  # decoded and saved by a process of its own (on the vehicle's node), never in this
  # connection (a pilot's commands would wait): the reply says `pending`, the event
  # `snapshot` follows to this connection.
  def handle_in("snapshot", _payload, socket) do
    id = id(socket)

    spawn(fn ->
      result =
        try do
          Neptunus.Camera.Snapshots.take(id, NeptunusWeb.API.Snapshots.dir())
        rescue
          exception -> {:error, :failed, Exception.message(exception)}
        catch
          kind, reason -> {:error, :failed, "snapshot failed: #{inspect({kind, reason})}"}
        end

      Channel.send_self(socket, {:snapshot, result})
    end)

    {:reply, {:ok, %{status: "pending"}}, socket}
  end

  def handle_in(event, _payload, socket) do
    {:reply, {:error, %{reason: "unknown event: #{event}"}}, socket}
  end

  @impl true
  def handle_info(:after_join, socket) do
    {:push, "presence_state", Presence.list(socket.topic), socket}
  end

  # The presence server restarted without this connection's presence (NeptunusWeb.Socket).
  def handle_info(:presence_restarted, socket) do
    socket = track(socket, socket.assigns.pilot)
    {:push, "presence_state", Presence.list(socket.topic), socket}
  end

  # Targeted events from the helm (see `party/1`).
  def handle_info({:helm, "control_granted" = event, payload}, socket) do
    {:push, event, payload, track(socket, true)}
  end

  def handle_info({:helm, "control_lost" = event, payload}, socket) do
    {:push, event, payload, track(socket, false)}
  end

  def handle_info({:helm, event, payload}, socket), do: {:push, event, payload, socket}

  def handle_info({:snapshot, {:ok, snapshot}}, socket),
    do: {:push, "snapshot", %{ok: true, snapshot: snapshot}, socket}

  def handle_info({:snapshot, {:error, _status, reason}}, socket),
    do: {:push, "snapshot", %{ok: false, reason: reason}, socket}

  # the vehicle's answer to an arm/disarm/autopilot whose reply said `pending`
  def handle_info({:vehicle_answer, _ref, event, result}, socket) do
    payload =
      case result do
        :ok -> %{command: event, ok: true}
        {:error, reason} -> %{command: event, ok: false, reason: reason}
      end

    {:push, "vehicle_answer", payload, socket}
  end

  @impl true
  def terminate(reason, socket) do
    # Leaving the vehicle's topic or disconnecting gives the helm up (and stops the vehicle).
    why =
      if reason in [{:shutdown, :left}, {:shutdown, :rejoin}],
        do: "pilot_left",
        else: "pilot_disconnected"

    if id = socket.assigns[:vehicle_id], do: Helm.leave(id, socket.user.id, why)
    :ok
  end

  defp vehicle_state(node, id) when node == node(), do: {:ok, vehicle_state(id)}

  defp vehicle_state(node, id) do
    {:ok, :erpc.call(node, __MODULE__, :vehicle_state, [id], 5_000)}
  catch
    :error, {:erpc, _} -> {:error, "vehicle unreachable: #{id}"}
    :exit, _ -> {:error, "vehicle unreachable: #{id}"}
  end

  @doc false
  # The vehicle's part of the join reply, on the vehicle's own node.
  @spec vehicle_state(String.t()) :: map()
  def vehicle_state(id) do
    helm = Helm.status(id)
    [vehicle] = Enum.filter(Fleet.list(), &(&1.id == id))

    %{
      vehicle: vehicle |> Map.put(:node, Atom.to_string(node())) |> Map.merge(abilities(id)),
      telemetry: Telemetry.latest(id),
      helm: helm,
      pilot: helm.pilot && %{name: helm.pilot.name},
      control: Control.status(id),
      mission: Control.mission(id),
      camera: camera(id),
      settings: ViewSettings.get(id)
    }
  end

  # what the vehicle can do, as the pages need it (its board's capabilities)
  defp abilities(id) do
    case Board.capabilities(id) do
      %{axes: axes, autopilots: autopilots} ->
        %{axes: Enum.map(axes, &Atom.to_string/1), autopilots: Atom.to_string(autopilots)}

      nil ->
        %{}
    end
  end

  defp session(socket) do
    %{
      id: socket.user.id,
      name: socket.user.name,
      role: Atom.to_string(socket.user.role),
      mode: Atom.to_string(Auth.mode())
    }
  end

  defp camera(id) do
    case Neptunus.Vehicle.Camera.info(id) do
      nil -> nil
      %{codec: codec} = info -> %{info | codec: Atom.to_string(codec)}
    end
  end

  # This connection as the helm sees it; the helm's targeted events come back to this
  # channel's handle_info/2 as {:helm, event, payload}.
  defp party(socket) do
    %{
      id: socket.user.id,
      name: socket.user.name,
      role: socket.user.role,
      pid: socket.transport_pid,
      notify: fn event, payload -> Channel.send_self(socket, {:helm, event, payload}) end
    }
  end

  defp track(socket, pilot?) do
    {:ok, _meta} =
      Presence.track(socket.transport_pid, socket.topic, socket.user.name, %{
        name: socket.user.name,
        role: Atom.to_string(socket.user.role),
        since: socket.assigns.since_wall_ms,
        online_at: socket.assigns.since_wall_ms,
        pilot: pilot?,
        conn: socket.user.id,
        node: Atom.to_string(node())
      })

    Channel.assign(socket, pilot: pilot?)
  end

  defp id(socket), do: socket.assigns.vehicle_id

  # the main station, or the user who pilots (from any of their connections: the developer
  # page beside the operator page)
  defp may_tune(_id, %{user: %{role: :main_station}}, _what), do: :ok

  defp may_tune(id, socket, what) do
    case Helm.status(id) do
      %{pilot: %{name: name}} when name == socket.user.name ->
        :ok

      _ ->
        {:error,
         "#{what} is for the pilot or the main station: #{socket.user.name} does not pilot"}
    end
  end

  # A request to the board answered asynchronously (`notify`), after the helm's pilot check.
  defp board_request(socket, event, request) do
    id = id(socket)
    ref = make_ref()
    notify = fn result -> Channel.send_self(socket, {:vehicle_answer, ref, event, result}) end
    topic = socket.topic

    with {:ok, _} <- Helm.board_request(id, party(socket), request, notify) do
      receive do
        {:channel_info, ^topic, {:vehicle_answer, ^ref, _event, :ok}} ->
          {:ok, %{status: "ok", control: on_vehicle(id, Control, :status, [id])}}

        {:channel_info, ^topic, {:vehicle_answer, ^ref, _event, {:error, r}}} ->
          {:error, r}
      after
        @vehicle_answer_ms ->
          {:ok, %{status: "pending", control: on_vehicle(id, Control, :status, [id])}}
      end
    end
    |> reply(socket)
  end

  # A call to one of the vehicle's processes, on the vehicle's node (here, or another node of
  # the fleet); a clear error when that node is cut off.
  defp on_vehicle(id, module, fun, args) do
    Fleet.on_vehicle_node(id, module, fun, args, {:error, "vehicle unreachable: #{id}"})
  end

  defp reply({:ok, response}, socket), do: {:reply, {:ok, response}, socket}
  defp reply({:error, reason}, socket), do: {:reply, {:error, %{reason: reason}}, socket}
end
