defmodule NeptunusWeb.MAVLinkE2ETest do
  # The operator page in Chromium (test/e2e/mavlink.e2e.mjs) flying a mavlink vehicle against
  # the fake ArduSub; afterwards, what the fake received says the page's commands reached it.
  use ExUnit.Case, async: false

  alias Neptunus.Test.FakeArduSub

  @moduletag :external
  @moduletag :capture_log
  @moduletag timeout: 120_000

  @root Path.expand("../..", __DIR__)

  test "fly a mavlink vehicle from the operator page" do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    fake = FakeArduSub.start!(:udp)
    id = "mav-e2e-#{System.unique_integer([:positive])}"
    link = {:udpout, "127.0.0.1", fake.udp}

    {:ok, _} =
      Neptunus.Fleet.start_vehicle(%{
        id: id,
        board: :mavlink,
        link: link,
        system: 255,
        component: 190
      })

    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")
    url = "http://127.0.0.1:#{Application.fetch_env!(:neptunus, :endpoint).port}"

    {output, status} =
      System.cmd(node, ["--test", "--test-reporter=spec", "test/e2e/mavlink.e2e.mjs"],
        cd: @root,
        env: [{"NEPTUNUS_URL", url}, {"E2E_MAVLINK_VEHICLE", id}],
        stderr_to_stdout: true
      )

    assert status == 0, "mavlink.e2e.mjs failed (exit #{status}):\n#{output}"
    refute output =~ ~r/fail [1-9]/

    # what the vehicle received, in order: armed, a forward MANUAL_CONTROL while armed, disarmed
    FakeArduSub.expect!(fake, &(&1["event"] == "armed" and &1["armed"] == true))

    FakeArduSub.expect!(
      fake,
      &(&1["event"] == "manual_control" and &1["x"] > 0 and &1["armed"] == true)
    )

    FakeArduSub.expect!(
      fake,
      &(&1["event"] == "manual_control" and &1["y"] > 0 and &1["armed"] == true)
    )

    FakeArduSub.expect!(fake, &(&1["event"] == "armed" and &1["armed"] == false))
  end
end
