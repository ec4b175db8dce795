defmodule Neptunus.E2E.ExternalTest do
  # Runs the Node-side suites against this test run's live server (the application under
  # test, on its test port): the official `phoenix` JS client over `ws`, and Playwright
  # driving Debian's Chromium. `make test` builds the assets and installs npm packages first.
  use ExUnit.Case, async: false

  @moduletag :external
  # a bound for a hung suite only (each Node test bounds its own waits)
  @moduletag timeout: 900_000

  @root Path.expand("../..", __DIR__)

  defp url, do: "http://127.0.0.1:#{Application.fetch_env!(:neptunus, :endpoint).port}"

  defp node!(args, env) do
    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")

    {output, status} =
      System.cmd(node, args,
        cd: @root,
        env: [{"NEPTUNUS_URL", url()} | env],
        stderr_to_stdout: true
      )

    assert status == 0, "node #{Enum.join(args, " ")} failed (exit #{status}):\n#{output}"
    output
  end

  # a `node --test` suite: it ran tests, and none failed
  defp node_suite!(script, env \\ []) do
    output = node!(["--test", "--test-reporter=spec", script], env)
    assert output =~ ~r/pass \d+/
    refute output =~ ~r/fail [1-9]/
  end

  test "the official phoenix JS client: join, presence, telemetry, helm, thrust, stop" do
    node_suite!("assets/test/protocol/vehicle.test.mjs")
  end

  test "the operator page in Chromium: keyboard, touch, gamepad, handover, safety stops, settings" do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # a second vehicle whose camera is the fake camera program (two JPEG images in turn)
    # (named to sort after neptunus-1: pages without ?vehicle= open the first vehicle)
    camera_vehicle = "z-e2e-cam-#{System.unique_integer([:positive])}"
    script = Path.join(@root, "test/fixtures/camera/fake_camera.sh")
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [script, "0"]}

    {:ok, _} =
      Neptunus.Fleet.start_vehicle(%{id: camera_vehicle, board: :simulated, camera: camera})

    try do
      node_suite!("test/e2e/operator.e2e.mjs", [
        {"E2E_CAMERA_VEHICLE", camera_vehicle}
      ])
    after
      Neptunus.Fleet.stop_vehicle(camera_vehicle)
    end
  end

  test "the developer page in Chromium: plots, reset, remove, CSV, logger, recordings" do
    unless File.exists?(Path.join(@root, "priv/static/dev.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # the server records to a scratch directory holding one recording of neptunus-1: 300
    # samples of a dive to 3 m, ten minutes ago (the developer page lists and replays it)
    dir =
      Path.join(
        System.tmp_dir!(),
        "neptunus-e2e-recordings-#{System.unique_integer([:positive])}"
      )

    File.rm_rf!(dir)
    NeptunusWeb.Test.Wire.settings!(recording_dir: dir)

    try do
      start = System.os_time(:millisecond) - 600_000
      name = Neptunus.Recording.file_name(DateTime.from_unix!(start, :millisecond), 1)
      path = Path.join([dir, "neptunus-1", name])
      File.mkdir_p!(Path.dirname(path))
      {:ok, log} = :disk_log.open(name: {__MODULE__, :e2e}, file: String.to_charlist(path))

      entries =
        for i <- 0..299 do
          {start + i * 50, "telemetry",
           %{t: i * 0.05, sent_at: start + i * 50, measurement: %{depth: i / 100, heading: 1.0}}}
        end

      :ok =
        :disk_log.log_terms(log, entries ++ [{start + 15_000, "stopped", %{reason: "deadman"}}])

      :ok = :disk_log.close(log)

      node_suite!("test/e2e/developer.e2e.mjs", [
        {"E2E_RECORDING", name}
      ])
    after
      File.rm_rf!(dir)
    end
  end

  test "login, roles and the main station's takeover in Chromium (secure mode)" do
    unless File.exists?(Path.join(@root, "priv/static/login.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # The test server switches to secure mode for this test (NeptunusWeb.Auth reads the
    # web settings at every connection and login).
    logins = %{"e2e-pilot" => "pilot pw", "e2e-main" => "main pw", "e2e-olga" => "olga pw"}
    roles = %{"e2e-pilot" => :pilot, "e2e-main" => :main_station, "e2e-olga" => :observer}

    users =
      Map.new(logins, fn {name, password} ->
        hash = NeptunusWeb.Auth.Password.hash(password, iterations: 1000)
        {name, %{name: name, role: Map.fetch!(roles, name), hash: hash}}
      end)

    NeptunusWeb.Test.Wire.settings!(
      auth: %{
        mode: :secure,
        secret: Base.encode64(:crypto.strong_rand_bytes(32)),
        users: users,
        anonymous_observers: false,
        origins: []
      }
    )

    NeptunusWeb.Auth.RateLimit.reset()

    node_suite!("test/e2e/login.e2e.mjs", [
      {"NEPTUNUS_E2E_LOGINS", :jiffy.encode(logins) |> IO.iodata_to_binary()}
    ])
  end
end
