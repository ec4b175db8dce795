defmodule Neptunus.E2E.ExternalTest do
  # Runs the Node-side suites against this test run's live server (the application under
  # test, on its test port): the official `phoenix` JS client over `ws`, and Playwright
  # driving Debian's Chromium. `make test` builds the assets and installs npm packages first.
  use ExUnit.Case, async: false

  @moduletag :external
  @moduletag timeout: 180_000

  @root Path.expand("../..", __DIR__)

  defp url, do: "http://127.0.0.1:#{Application.fetch_env!(:neptunus, :endpoint).port}"

  defp node!(args) do
    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")

    {output, status} =
      System.cmd(node, args, cd: @root, env: [{"NEPTUNUS_URL", url()}], stderr_to_stdout: true)

    assert status == 0, "node #{Enum.join(args, " ")} failed (exit #{status}):\n#{output}"
    output
  end

  test "the official phoenix JS client: join, presence, telemetry, thrust, stop" do
    output = node!(["--test", "--test-reporter=spec", "assets/test/protocol/vehicle.test.mjs"])
    assert output =~ ~r/pass \d+/
    refute output =~ ~r/fail [1-9]/
  end

  test "the operator page in Chromium: keys drive the simulated vehicle" do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    output = node!(["--test", "--test-reporter=spec", "test/e2e/operator.e2e.mjs"])
    assert output =~ ~r/pass \d+/
    refute output =~ ~r/fail [1-9]/
  end
end
