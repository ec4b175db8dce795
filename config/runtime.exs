import Config

# Every environment variable is read and validated here. A malformed value stops
# the node with a message saying what to set (Neptunus.Config raises ArgumentError).
#
#   NEPTUNUS_PORT      HTTP/WebSocket port            (default 4000; 4102 under `mix test`)
#   NEPTUNUS_BIND      address to listen on           (default 127.0.0.1)
#   NEPTUNUS_VEHICLES  id=board[,id=board...]         (default neptunus-1=simulated)
#   NEPTUNUS_WIRING    id=wiring[,...]                (sitl/uart motors, modifiers; thesis wiring)
#   NEPTUNUS_FIRMWARE  id=openrov-2.5|openrov-30[,...] (sitl/uart firmware line; openrov-2.5)
#
# Security (Neptunus.Config.Auth, Neptunus.Config.TLS): NEPTUNUS_SECRET, NEPTUNUS_USERS_FILE,
# NEPTUNUS_USERS, NEPTUNUS_ANONYMOUS_OBSERVERS, NEPTUNUS_ORIGINS, NEPTUNUS_TOKEN_TTL_S,
# NEPTUNUS_LOGIN_ATTEMPTS, NEPTUNUS_TLS_CERT, NEPTUNUS_TLS_KEY. Bound to anything but
# loopback without a secret and users, the node refuses to start.
# Helm (Neptunus.Config.Helm): NEPTUNUS_DEADMAN_MS, NEPTUNUS_REQUEST_TIMEOUT_MS,
# NEPTUNUS_TAKEOVER_MS.
# Recording (Neptunus.Config.Recording): NEPTUNUS_RECORDINGS (directory or off),
# NEPTUNUS_RECORDING_MAX_MB, NEPTUNUS_RECORDING_MIN_FREE_MB, NEPTUNUS_RECORDING_KEEP_DAYS.
# Settings (Neptunus.Config.Settings, Neptunus.Settings): NEPTUNUS_SETTINGS, the per-user and
# per-vehicle settings' directory (default settings).
# Firmware (Neptunus.FirmwareRecord): NEPTUNUS_FIRMWARE_RECORD, the SD-card image's record of
# its last update (kept or rolled back), shown by /api/health and the operator page.
# Scheduling (Neptunus.Config.OS, Neptunus.OS): NEPTUNUS_OS_SLICE_US.
# Connections (Neptunus.Config.Endpoint, NeptunusWeb.Endpoint):
# NEPTUNUS_MAX_CONNECTIONS, the most client connections at once (1..1048576); more are closed
# as soon as they are accepted. Unset: derived from the file descriptor limit, leaving room
# for files, port programs and recordings (and a configured value is lowered to that).
env = System.get_env()

endpoint =
  env
  |> Neptunus.Config.Endpoint.endpoint!(Application.get_env(:neptunus, :default_port, 4000))
  |> Map.put(:tls, Neptunus.Config.TLS.tls!(env))
  |> Map.put(:max_connections, Neptunus.Config.Endpoint.max_connections!(env))

# Fleet (Neptunus.Config.Cluster): NEPTUNUS_NODE, NEPTUNUS_COOKIE, NEPTUNUS_CLUSTER,
# NEPTUNUS_DIST_CERT, NEPTUNUS_DIST_KEY, NEPTUNUS_DIST_CACERT. Unset NEPTUNUS_NODE: one node.
config :neptunus, cluster: Neptunus.Config.Cluster.cluster!(env)

config :neptunus,
  endpoint: endpoint,
  vehicles: Neptunus.Config.Vehicles.vehicles!(env),
  auth: Neptunus.Config.Auth.auth!(env, endpoint),
  helm: Neptunus.Config.Helm.helm!(env),
  os_time_slice_ns: Neptunus.Config.OS.os_time_slice_ns!(env),
  recording:
    Neptunus.Config.Recording.recording!(
      env,
      Application.get_env(:neptunus, :default_recordings, "recordings")
    ),
  firmware_record:
    (case String.trim(Map.get(env, "NEPTUNUS_FIRMWARE_RECORD", "")) do
       "" -> nil
       path -> path
     end),
  settings_dir:
    Neptunus.Config.Settings.settings_dir!(
      env,
      Application.get_env(:neptunus, :default_settings, "settings")
    )
