defmodule NeptunusWeb.Channels.VehicleChannel do
  @moduledoc """
  Topic `vehicle:<id>`: one vehicle's telemetry, state changes, presence and the pilot's
  commands. The channel decides nothing: it hands commands to the vehicle's processes and
  relays their answers (see `docs/API.md` for payloads and error reasons).

  Join reply (state snapshot):
  `%{vehicle: %{id, board}, telemetry: payload | nil, pilot: %{name} | nil, control: %{...}}`,
  followed by `presence_state` pushed to the joiner. Events pushed by the server:
  `telemetry`, `pilot`, `stopped`, `presence_diff`.

  Client events: `thrust`, `stop`. Anything else is refused with a reason.
  """
  @behaviour NeptunusWeb.Channel

  alias Neptunus.Fleet
  alias Neptunus.Vehicle.{Control, Telemetry}
  alias NeptunusWeb.{Channel, Presence}

  @impl true
  def join("vehicle:" <> id = topic, _payload, socket) do
    if Fleet.exists?(id) do
      {:ok, _meta} =
        Presence.track(socket.transport_pid, topic, socket.user.name, %{
          online_at: System.os_time(:millisecond),
          node: Atom.to_string(node())
        })

      Channel.send_self(socket, :after_join)
      {:ok, snapshot(id), Channel.assign(socket, vehicle_id: id)}
    else
      {:error, %{reason: "unknown vehicle: #{id}"}}
    end
  end

  @impl true
  def handle_in("thrust", payload, socket) do
    socket.assigns.vehicle_id |> Control.thrust(caller(socket), payload) |> reply(socket)
  end

  def handle_in("stop", payload, socket) do
    reason =
      case payload do
        %{"reason" => reason} when is_binary(reason) and byte_size(reason) in 1..100 -> reason
        _ -> "pilot_stop"
      end

    socket.assigns.vehicle_id |> Control.stop(caller(socket), reason) |> reply(socket)
  end

  def handle_in(event, _payload, socket) do
    {:reply, {:error, %{reason: "unknown event: #{event}"}}, socket}
  end

  @impl true
  def handle_info(:after_join, socket) do
    {:push, "presence_state", Presence.list(socket.topic), socket}
  end

  @impl true
  def terminate(reason, socket) do
    # A pilot who leaves the vehicle's topic or disconnects stops the vehicle.
    why =
      if reason in [{:shutdown, :left}, {:shutdown, :rejoin}],
        do: "pilot_left",
        else: "pilot_disconnected"

    if id = socket.assigns[:vehicle_id], do: Control.release(id, caller(socket), why)
    :ok
  end

  defp snapshot(id) do
    status = Control.status(id)
    [vehicle] = Enum.filter(Fleet.list(), &(&1.id == id))

    %{
      vehicle: vehicle,
      telemetry: Telemetry.latest(id),
      pilot: status.pilot,
      control: Map.take(status, [:command, :thrusters, :gain])
    }
  end

  defp caller(socket), do: %{pid: socket.transport_pid, name: socket.user.name}

  defp reply({:ok, response}, socket), do: {:reply, {:ok, response}, socket}
  defp reply({:error, reason}, socket), do: {:reply, {:error, %{reason: reason}}, socket}
end
