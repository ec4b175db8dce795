# The application runs under test on its own port (config/test.exs): the wire, Node and
# browser tests talk to it exactly as a browser would.
#
# Tags:
#   :external — runs Node (protocol client, Playwright). Included by default; `make test`
#               builds what they need first. Skip with `mix test --exclude external`.
#   :target   — the slow release tests (the armhf tarball under qemu-user, install/update/
#               rollback of built releases): excluded here; `make test-target` builds the
#               tarball and runs them (`mix test --only target`).
#   :firmware — the SD-card image booted under qemu-system-arm (updates, rollback, power
#               loss): excluded here; `make test-firmware` builds the image and runs them.
{:ok, _} = Application.ensure_all_started(:inets)
#
# After ExUnit's summary, Neptunus.Test.FailureRecap repeats which tests failed and the end
# of their reports (a CI log often keeps only its tail).
ExUnit.start(
  exclude: [:target, :firmware],
  formatters: [ExUnit.CLIFormatter, Neptunus.Test.FailureRecap]
)
