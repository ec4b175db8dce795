defmodule NeptunusWeb.Channels.VehicleChannel do
  @moduledoc """
  Topic `vehicle:<id>`: one vehicle's telemetry, helm, presence and the pilot's commands.
  The channel decides nothing: it hands every command to the vehicle's
  `Neptunus.Vehicle.Helm` (which checks that the sender is the pilot and carries the
  command out) and relays the answers. Payloads and error reasons: `docs/API.md`.

  Join reply (state snapshot): `%{vehicle, telemetry, helm, pilot, control, camera, session}`
  (`camera`: `%{url}` of the MJPEG stream, or nil),
  followed by `presence_state`. Joining never depends on control: observers join like
  pilots, and being refused control is an event, never a closed channel.

  Client events: `clock` (anyone: the server's wall clock in ms, `%{now}`), `thrust`,
  `stop`, `heartbeat`, `request_control`, `answer_request`,
  `take_control`, `release_control`, `sim_reset`, `sim_set`, and the control commands
  `set_control_mode`, `set_gain`, `set_lights`, `set_laser`, `set_tilt`, `autopilot`,
  `set_run_mode` (`Neptunus.Vehicle.Control.command/3`). Server events: `telemetry`, `helm`, `stopped`,
  `presence_diff` (broadcast), and to one connection only `control_request`,
  `control_granted`, `control_lost`, `request_denied`. A vehicle on another node of the
  fleet is joined the same way (its snapshot is made there, its helm called there); this
  node says `unreachable` and `reachable` when that node is cut off and back
  (`Neptunus.Fleet.Directory`).

  Presence: keyed by user name, one meta per connection:
  `%{name, role, since, pilot, conn, node, online_at}`; `pilot` is updated on every grant and
  loss of control. When the presence server restarts (`:presence_restarted`), the channel
  tracks again and pushes `presence_state` anew: the client's presences are right again.
  """
  @behaviour NeptunusWeb.Channel

  alias Neptunus.Fleet
  alias Neptunus.Vehicle.{Control, Helm, Telemetry}
  alias NeptunusWeb.{Auth, Channel, Presence}

  @control_events ~w(set_control_mode set_gain set_lights set_laser set_tilt autopilot set_run_mode)

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
      socket = Channel.assign(socket, vehicle_id: id, since: System.os_time(:millisecond))
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
    {:reply, {:ok, %{now: System.os_time(:microsecond) / 1000}}, socket}
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

  # Control commands (Neptunus.Vehicle.Control.command/3): pilot only, through the helm like
  # every command, so no handover can come between the check and the command.
  def handle_in(event, payload, socket) when event in @control_events do
    id = id(socket)

    id
    |> Helm.command(party(socket), :none, fn -> Control.command(id, event, payload) end)
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
      vehicle: Map.put(vehicle, :node, Atom.to_string(node())),
      telemetry: Telemetry.latest(id),
      helm: helm,
      pilot: helm.pilot && %{name: helm.pilot.name},
      control: Control.status(id),
      camera: camera(id)
    }
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
    case Neptunus.Vehicle.Camera.url(id) do
      nil -> nil
      url -> %{url: url}
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
        since: socket.assigns.since,
        online_at: socket.assigns.since,
        pilot: pilot?,
        conn: socket.user.id,
        node: Atom.to_string(node())
      })

    Channel.assign(socket, pilot: pilot?)
  end

  defp id(socket), do: socket.assigns.vehicle_id

  defp reply({:ok, response}, socket), do: {:reply, {:ok, response}, socket}
  defp reply({:error, reason}, socket), do: {:reply, {:error, %{reason: reason}}, socket}
end
