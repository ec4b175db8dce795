defmodule NeptunusWeb.Channels.LogChannel do
  @moduledoc """
  Topic `log:<id>`: the developer logger's entries for vehicle `id`, as the vehicle's
  processes publish them on the PubSub topic `Neptunus.Vehicle.Telemetry.log_topic/1`.

  Anyone connected may join (observers included): the log is read-only and carries nothing
  the vehicle topic does not already show. The entries reach the browser as the broadcast
  event `log` (encoded once per broadcast, see `Neptunus.PubSub`), payload:

      %{category: "safety", level: "warning", message: "stopped: deadman",
        at: 1795000000000, ...fields of the category}

  Join reply: `%{vehicle: id}`. Joining an unknown vehicle is refused with
  `unknown vehicle: <id>`. There are no client events: every push is answered with
  `error` `unknown event on log: <event>`.
  """
  @behaviour NeptunusWeb.Channel

  alias Neptunus.Fleet

  @impl true
  def join("log:" <> id, _payload, socket) do
    if Fleet.exists?(id) do
      {:ok, %{vehicle: id}, socket}
    else
      {:error, %{reason: "unknown vehicle: #{id}"}}
    end
  end

  @impl true
  def handle_in(event, _payload, socket),
    do: {:reply, {:error, %{reason: "unknown event on log: #{event}"}}, socket}

  @impl true
  def handle_info(_msg, socket), do: {:noreply, socket}

  @impl true
  def terminate(_reason, _socket), do: :ok
end
