defmodule Neptunus.Application do
  @moduledoc """
  The node's supervision tree (docs/ARCHITECTURE.md):

      Neptunus.Application        one_for_one
      ├── Neptunus.PubSub         :pg scope, topic fan-out
      ├── Neptunus.PubSub.Relay   other nodes' broadcasts to this node's subscribers
      ├── Neptunus.Settings       per-user and per-vehicle settings, on disk
      ├── Neptunus.Fleet          directory scope, registry, one supervisor per vehicle
      ├── Neptunus.GCS            (NEPTUNUS_MAVLINK_SERVE only) ground stations over MAVLink
      ├── NeptunusWeb.Presence    who watches which topic
      ├── NeptunusWeb.Endpoint    yaws: static files, HTTP API, WebSocket (last up, first down)
      └── Neptunus.Fleet.Connector  (a fleet's node only) connects to NEPTUNUS_CLUSTER

  A node named by `NEPTUNUS_NODE` starts distribution before all of them
  (`Neptunus.Fleet.Distribution`): without it, the node is a single node as before.

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
    # the configuration is read here, once: the processes get their settings as options
    app_env = Application.get_all_env(:neptunus)
    # before the vehicles start their port programs (which ask for the same slice)
    Neptunus.OS.apply_configured(Keyword.get(app_env, :os_time_slice_ns))
    # before the port programs and the endpoint: they inherit and size by it
    Neptunus.OS.apply_fd_limit()
    # before anything joins a :pg scope: a fleet's node is named before its vehicles publish
    cluster = Keyword.get(app_env, :cluster)

    case Neptunus.Fleet.Distribution.start(cluster) do
      :ok -> :ok
      {:error, message} -> raise ArgumentError, message
    end

    web = Neptunus.Config.Endpoint.web_settings!(app_env)
    settings = vehicle_settings(app_env)
    vehicles = Enum.map(Keyword.fetch!(app_env, :vehicles), &Map.merge(settings, &1))

    children = [
      # the fastlane subscribers are WebSocket connections: frames in the Channels format
      {Neptunus.PubSub, encoder: NeptunusWeb.Channels.Wire},
      # serves this node's subscribers the frames of other nodes' broadcasts
      Neptunus.PubSub.Relay,
      {Neptunus.Settings, dir: Keyword.fetch!(app_env, :settings_dir)},
      {Neptunus.Fleet, vehicles}
    ]

    # ground stations over MAVLink (NEPTUNUS_MAVLINK_SERVE): after the vehicles they serve
    children =
      case Keyword.get(app_env, :gcs) do
        %{endpoints: [_ | _]} = gcs -> children ++ [{Neptunus.GCS, gcs: gcs, vehicles: vehicles}]
        _ -> children
      end

    children =
      children ++
        [
          NeptunusWeb.Presence,
          {NeptunusWeb.Endpoint, web}
        ]

    # the fleet's other nodes, connected once this node serves (a single node: none)
    children =
      case cluster do
        %{cluster: [_ | _] = nodes} -> children ++ [{Neptunus.Fleet.Connector, nodes}]
        _ -> children
      end

    with {:ok, pid} <-
           Supervisor.start_link(children, strategy: :one_for_one, name: Neptunus.Supervisor) do
      Logger.info(
        "Neptunus #{Application.spec(:neptunus, :vsn)} serving #{NeptunusWeb.Endpoint.url()} " <>
          "with vehicles #{Enum.map_join(vehicles, ", ", &"#{&1.id} (#{&1.board})")}"
      )

      {:ok, pid}
    end
  end

  @vehicle_keys [
    :telemetry_hz,
    :sim_hz,
    :fanout_slice,
    :fanout_gap_ms,
    :helm,
    :recording,
    :os_time_slice_ns
  ]

  @doc """
  The node-wide settings every configured vehicle gets as options of its processes (pure):
  those of #{inspect(@vehicle_keys)} that the application's environment `app_env` sets.
  The configuration is read here, once; a vehicle's own map (e.g. `helm:` of a test
  vehicle) wins over these. Unset keys are left out: each process has its default.

      iex> Neptunus.Application.vehicle_settings(telemetry_hz: 10, endpoint: %{}, helm: [deadman_ms: 800])
      %{telemetry_hz: 10, helm: [deadman_ms: 800]}
  """
  @spec vehicle_settings(keyword()) :: map()
  def vehicle_settings(app_env) do
    app_env
    |> Keyword.take(@vehicle_keys)
    |> Enum.reject(fn {_key, value} -> is_nil(value) end)
    |> Map.new()
  end
end
