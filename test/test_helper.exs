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
#
# After ExUnit's summary, Neptunus.Test.FailureRecap repeats which tests failed and the end
# of their reports (a CI log often keeps only its tail).
#
# A wait for an event (`assert_receive` without a timeout, the waits in test/support) gives up
# after Neptunus.Test.Patience.ms/0: generous, since the machine may be busy; it returns as soon
# as the event comes. A test is ended as hung after 5 minutes (ExUnit's 60 s default was too
# short for the property tests' CPU work on a machine busy with other programs).
{:ok, _} = Application.ensure_all_started(:inets)

ExUnit.start(
  exclude: [:target, :firmware],
  formatters: [ExUnit.CLIFormatter, Neptunus.Test.FailureRecap],
  assert_receive_timeout: Neptunus.Test.Patience.ms(),
  timeout: 300_000
)
