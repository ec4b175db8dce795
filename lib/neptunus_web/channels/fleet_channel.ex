defmodule NeptunusWeb.Channels.FleetChannel do
  @moduledoc """
  Topic `fleet`: the vehicles of the fleet, every node's (`Neptunus.Fleet.directory/0`).
  Join reply `%{vehicles: [%{id, board, node, status, helm, pilot, link, depth, heading, recording}]}`; `status` is
  `"up"` or `"unreachable"` (its node is cut off).

  Pushes (to every client of this node at once, encoded once): `vehicles` `%{vehicles: [...]}`
  when the directory changed, at most once a second (`Neptunus.Fleet.Overview`);
  `unreachable` `%{id, node, reason}` and `reachable` `%{id, node}` at once when a vehicle's
  node is cut off or back (`Neptunus.Fleet.Directory`).
  No client events yet; any push is answered with an error naming the event.
  """
  @behaviour NeptunusWeb.Channel

  @impl true
  def join("fleet", _payload, socket), do: {:ok, %{vehicles: Neptunus.Fleet.directory()}, socket}

  @impl true
  def handle_in(event, _payload, socket),
    do: {:reply, {:error, %{reason: "unknown event on fleet: #{event}"}}, socket}

  @impl true
  def handle_info(_msg, socket), do: {:noreply, socket}

  @impl true
  def terminate(_reason, _socket), do: :ok
end
