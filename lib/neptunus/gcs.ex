defmodule Neptunus.GCS do
  @moduledoc """
  Ground stations — QGroundControl, Cockpit, MAVProxy, pymavlink scripts — see and fly the
  node's vehicles over MAVLink (docs/MAVLINK.md, "Ground stations"). Started by
  `Neptunus.Application` after the fleet when `NEPTUNUS_MAVLINK_SERVE` names endpoints
  (`Neptunus.Config.GCS`).

      Neptunus.GCS                        rest_for_one
      ├── Registry Neptunus.GCS.Names     the sources' and endpoints' names
      ├── Registry Neptunus.GCS.Registry  sessions listening to each vehicle {:vehicle, sysid}
      ├── Neptunus.GCS.Replay             signed streams' last timestamps (replay protection)
      ├── Task.Supervisor Neptunus.GCS.Tasks   sessions' slow intents
      ├── DynamicSupervisor Neptunus.GCS.Links one Neptunus.GCS.Link per session
      ├── Neptunus.GCS.Source …           one per vehicle: its messages, encoded once
      └── Neptunus.GCS.Endpoint …         one per endpoint: its socket, its sessions

  Every vehicle of the node is a MAVLink system (`Neptunus.GCS.Vehicle`) with the system
  id `NEPTUNUS_MAVLINK_SYSIDS` gives it; each session (`Neptunus.GCS.Link`, deciding with
  `Neptunus.GCS.Session`) is a party on the vehicles' helms like a browser's connection.

  `rest_for_one`: when a registry or the replay table restarts, every session restarts with
  it (its party leaves the helms, which stop their vehicles); a source or an endpoint alone
  restarts alone (an endpoint's sessions end with it: they watch it).
  """
  use Supervisor

  @doc """
  Options: `:gcs` (`t:Neptunus.Config.GCS.t/0`), `:vehicles` (the node's vehicles as
  configured: `%{id, board}` and, for `uart`/`sitl`, `wiring`), `:timeout_ms` (a session's
  silence, default 5 000), `:hz` (the sources' rate, default 20).
  """
  @spec start_link(keyword()) :: Supervisor.on_start()
  def start_link(opts), do: Supervisor.start_link(__MODULE__, opts, name: __MODULE__)

  @impl true
  def init(opts) do
    gcs = Keyword.fetch!(opts, :gcs)
    configured = Keyword.fetch!(opts, :vehicles)

    vehicles =
      for v <- configured, Map.has_key?(gcs.systems, v.id), into: %{} do
        {Map.fetch!(gcs.systems, v.id), %{id: v.id, board: v.board, wiring: Map.get(v, :wiring)}}
      end

    admission = Map.take(gcs, [:keys, :mode, :trusted, :unsigned])
    timeout_ms = Keyword.get(opts, :timeout_ms, 5_000)

    sources =
      for {sysid, v} <- Enum.sort(vehicles) do
        {Neptunus.GCS.Source,
         id: v.id, sysid: sysid, board: v.board, hz: Keyword.get(opts, :hz, 20)}
      end

    endpoints =
      for endpoint <- gcs.endpoints do
        {Neptunus.GCS.Endpoint,
         endpoint: endpoint, admission: admission, vehicles: vehicles, timeout_ms: timeout_ms}
      end

    children =
      [
        {Registry, keys: :unique, name: Neptunus.GCS.Names},
        {Registry, keys: :duplicate, name: Neptunus.GCS.Registry},
        Neptunus.GCS.Replay,
        {Task.Supervisor, name: Neptunus.GCS.Tasks},
        {DynamicSupervisor, name: Neptunus.GCS.Links, strategy: :one_for_one}
      ] ++ sources ++ endpoints

    Supervisor.init(children, strategy: :rest_for_one)
  end
end
