import Config

# The test suite runs the real application on its own port so the wire, Node and
# browser tests talk to it exactly as a browser would.
config :neptunus, default_port: 4102

# recording is off under test; the recorder and API tests record to their own directories
config :neptunus, default_recordings: "off"

# the settings store writes under the build directory (each worktree its own), not ./settings
config :neptunus, default_settings: Path.expand("../_build/test/settings", __DIR__)

# the slow-client tests wait for the send timeout: 2 s, still far beyond a healthy client
config :neptunus, send_timeout_ms: 2_000
