defmodule Neptunus.Application do
  @moduledoc """
  The node's supervision tree (docs/ARCHITECTURE.md):

      Neptunus.Application        one_for_one
      ├── Neptunus.PubSub         :pg scope, topic fan-out
      ├── Neptunus.Fleet          registry + one supervisor per vehicle
      ├── NeptunusWeb.Presence    who watches which topic
      └── NeptunusWeb.Endpoint    yaws: static files, HTTP API, WebSocket (last up, first down)

  Restart intensity: the default, 3 restarts in 5 s. A restart of PubSub or Presence is
  cheap and tells every client (docs/API.md), so a single crash, or a few spread over time,
  is absorbed; a node where they crash more often than that has a fault that restarting
  does not cure, and the application stops (its vehicles driven neutral as their processes
  shut down) for the service manager to start the node again. The chaos test spaces its
  kills of these processes as real failures would be (2 s apart).
  """
  use Application

  require Logger

  @impl true
  def start(_type, _args) do
    # before the vehicles start their port programs (which ask for the same slice)
    Neptunus.OS.apply_configured()
    # before the port programs and the endpoint: they inherit and size by it
    Neptunus.OS.apply_fd_limit()
    endpoint = Application.fetch_env!(:neptunus, :endpoint)
    vehicles = Application.fetch_env!(:neptunus, :vehicles)

    children = [
      Neptunus.PubSub,
      {Neptunus.Fleet, vehicles},
      NeptunusWeb.Presence,
      {NeptunusWeb.Endpoint, endpoint}
    ]

    with {:ok, pid} <-
           Supervisor.start_link(children, strategy: :one_for_one, name: Neptunus.Supervisor) do
      Logger.info(
        "Neptunus #{Application.spec(:neptunus, :vsn)} serving #{NeptunusWeb.Endpoint.url()} " <>
          "with vehicles #{Enum.map_join(vehicles, ", ", &"#{&1.id} (#{&1.board})")}"
      )

      {:ok, pid}
    end
  end
end
