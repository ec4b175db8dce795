import Config

# Compile-time defaults. Environment variables are read and validated in
# config/runtime.exs (see Neptunus.Config).
config :neptunus,
  # telemetry broadcast rate on "vehicle:<id>" (Hz)
  telemetry_hz: 20,
  # simulator integration rate (Hz)
  sim_hz: 100,
  # while someone pilots, observers' telemetry goes out in slices of at least this many
  # connections, one slice every fanout_gap_ms, within half the period, so a crowd of
  # observers never holds the cores for a whole burst (Neptunus.PubSub.broadcast_paced/5;
  # the pilot's connection is served first)
  fanout_slice: 50,
  fanout_gap_ms: 2,
  # a piloting connection runs at :high while it sends at most this many frames per second
  # (NeptunusWeb.Socket.FlowControl)
  pilot_frames_per_s: 200,
  # a connection with this many messages waiting drops stale telemetry frames: its client
  # reads slower than the telemetry arrives (NeptunusWeb.Socket.FlowControl); and the kernel holds at
  # most socket_unsent_bytes of a connection's frames unsent (Linux, TCP_NOTSENT_LOWAT)
  socket_backlog: 8,
  socket_unsent_bytes: 4_096,
  # a send to a client that has not read for this long closes the connection
  # (NeptunusWeb.Endpoint)
  send_timeout_ms: 15_000

config :logger, :console, format: "$time [$level] $message\n"

import_config "#{config_env()}.exs"
