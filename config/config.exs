import Config

# Compile-time defaults. Environment variables are read and validated in
# config/runtime.exs (see Neptunus.Config).
config :neptunus,
  # telemetry broadcast rate on "vehicle:<id>" (Hz)
  telemetry_hz: 20,
  # simulator integration rate (Hz)
  sim_hz: 100

config :logger, :console, format: "$time [$level] $message\n"

import_config "#{config_env()}.exs"
