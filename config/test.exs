import Config

# The test suite runs the real application on its own port so the wire, Node and
# browser tests talk to it exactly as a browser would.
config :neptunus, default_port: 4102

config :logger, level: :warning
