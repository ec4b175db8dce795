import Config

# Every environment variable is read and validated here. A malformed value stops
# the node with a message saying what to set (Neptunus.Config raises ArgumentError).
#
#   NEPTUNUS_PORT      HTTP/WebSocket port            (default 4000; 4102 under `mix test`)
#   NEPTUNUS_BIND      address to listen on           (default 127.0.0.1)
#   NEPTUNUS_VEHICLES  id=board[,id=board...]         (default neptunus-1=simulated)
env = System.get_env()

config :neptunus,
  endpoint: Neptunus.Config.endpoint!(env, Application.get_env(:neptunus, :default_port, 4000)),
  vehicles: Neptunus.Config.vehicles!(env)
