import Config

# Settings of every environment. Environment variables are read and validated in
# config/runtime.exs (see Neptunus.Config).
#
# Tuning, all optional: each default is written once, in the module named (set a key here
# or in <env>.exs to override it). Read once: the vehicles' settings by Neptunus.Application,
# which passes them to each vehicle's processes as options.
#
#   telemetry_hz         telemetry broadcast rate on "vehicle:<id>" (Hz; Neptunus.Vehicle.Telemetry)
#   sim_hz               simulator integration rate (Hz; Neptunus.Sim.default_hz/0)
#   fanout_slice,        while someone pilots, observers' telemetry goes out in slices of at
#   fanout_gap_ms        least fanout_slice connections, one slice every fanout_gap_ms, within
#                        half the period, so a crowd of observers never holds the cores for a
#                        whole burst (Neptunus.Vehicle.Telemetry, Neptunus.PubSub.broadcast_paced/5;
#                        the pilot's connection is served first)
#
# The web layer's (read once at boot into NeptunusWeb.Endpoint.Settings; defaults in
# Neptunus.Config.Endpoint.web_settings!/1):
#
#   send_timeout_ms      a send to a client that has not read for this long closes the
#                        connection (NeptunusWeb.Endpoint)
#   header_timeout_ms    the most time a client has to send a request's head
#   socket_idle_timeout_ms  a WebSocket silent this long is closed (NeptunusWeb.Socket)
#   pilot_frames_per_s   a piloting connection runs at :high while it sends at most this many
#                        frames per second (NeptunusWeb.Socket.FlowControl)
#   socket_backlog       a connection with this many messages waiting drops stale telemetry
#                        frames: its client reads slower than the telemetry arrives
#   socket_unsent_bytes  the kernel holds at most this many bytes of a connection's frames
#                        unsent (Linux, TCP_NOTSENT_LOWAT)

config :logger, :console, format: "$time [$level] $message\n"

import_config "#{config_env()}.exs"
