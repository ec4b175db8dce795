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
    output
  end

  test "the official phoenix JS client: join, presence, telemetry, helm, thrust, stop" do
    node_suite!("assets/test/protocol/vehicle.test.mjs")
  end

  test "the operator page in Chromium: keyboard, touch, gamepad, handover, safety stops, settings" do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # a second vehicle whose camera is the fake camera program (two JPEG images in turn, MJPEG)
    # (named to sort after neptunus-1: pages without ?vehicle= open the first vehicle)
    camera_vehicle = "z-e2e-cam-#{System.unique_integer([:positive])}"
    script = Path.join(@root, "test/fixtures/camera/fake_camera.sh")
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [script, "0"]}

    {:ok, _} =
      Neptunus.Fleet.start_vehicle(%{id: camera_vehicle, board: :simulated, camera: camera})

    # and one without a camera (the simulated vehicles of the configuration have the sim camera)
    no_camera = "z-e2e-nocam-#{System.unique_integer([:positive])}"
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: no_camera, board: :simulated})

    try do
      node_suite!("test/e2e/operator.e2e.mjs", [
        {"E2E_CAMERA_VEHICLE", camera_vehicle},
        {"E2E_NO_CAMERA_VEHICLE", no_camera}
      ])
    after
      Neptunus.Fleet.stop_vehicle(camera_vehicle)
      Neptunus.Fleet.stop_vehicle(no_camera)
    end
  end

  @tag timeout: 400_000
  test "position, position hold and a mission on the map in Chromium (tablet, touch and mouse)" do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # a simulated vehicle with the simulated DVL and USBL (read by the real drivers over
    # their protocols on loopback) in a 0.1 m/s current from the west
    vehicle = "z-e2e-pos-#{System.unique_integer([:positive])}"

    {:ok, _} =
      Neptunus.Fleet.start_vehicle(%{
        id: vehicle,
        board: :simulated,
        sim: [current: {0.0, 0.1, 0.0}],
        position: [{:sim_dvl, []}, {:sim_usbl, []}]
      })

    try do
      output = node_suite!("test/e2e/position.e2e.mjs", [{"E2E_POSITION_VEHICLE", vehicle}])
      # the figures it measured (diagnostics)
      for line <- String.split(output, "\n"), line =~ "p95", do: IO.puts(String.trim(line))
    after
      Neptunus.Fleet.stop_vehicle(vehicle)
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

  @tag timeout: 900_000
  test "the video in Chromium: both decode paths, yaw, late joiner, throttled viewer, camera restart, snapshots" do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # three vehicles: the sim camera; a camera that ends every 4 s (and alternates its size);
    # a heavy one (about 3 Mbit/s) for the throttled viewer. Snapshots need a recordings directory.
    n = System.unique_integer([:positive])
    dir = Path.join(System.tmp_dir!(), "neptunus-e2e-video-#{n}")
    File.rm_rf!(dir)
    File.mkdir_p!(Path.join(dir, "state"))
    NeptunusWeb.Test.Wire.settings!(recording_dir: dir)
    script = Path.join(@root, "test/fixtures/camera/h264_camera.sh")
    {:ok, sim} = Neptunus.Camera.Source.parse("sim")

    vehicles = [
      {"z-e2e-video-#{n}", sim},
      {"z-e2e-restart-#{n}",
       %{
         kind: :exec,
         codec: :h264,
         program: "/bin/sh",
         args: [script, "4", Path.join(dir, "state")]
       }},
      {"z-e2e-busy-#{n}",
       %{kind: :exec, codec: :h264, program: "/bin/sh", args: [script, "0", "-", "noise"]}}
    ]

    try do
      for {id, camera} <- vehicles,
          do:
            {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, camera: camera})

      [{video, _}, {restart, _}, {busy, _}] = vehicles

      node_suite!("test/e2e/video.e2e.mjs", [
        {"E2E_VIDEO_VEHICLE", video},
        {"E2E_RESTART_VEHICLE", restart},
        {"E2E_BUSY_VEHICLE", busy}
      ])
    after
      for {id, _} <- vehicles, do: Neptunus.Fleet.stop_vehicle(id)
      File.rm_rf!(dir)
    end
  end

  test "the replay page in Chromium: a dive's video, HUD and plots in sync, controls, keys, touch" do
    unless File.exists?(Path.join(@root, "priv/static/replay.html")),
      do: flunk("priv/static is not built: run `make assets`")

    # the server's recordings: one dive of neptunus-1, 6 s of H.264 at 15 fps (a keyframe a
    # second) from ffmpeg's test pattern, telemetry at 20 Hz down to 3 m, a handover, a stop,
    # an autopilot change and a snapshot
    dir =
      Path.join(System.tmp_dir!(), "neptunus-e2e-replay-#{System.unique_integer([:positive])}")

    File.rm_rf!(dir)
    NeptunusWeb.Test.Wire.settings!(recording_dir: dir)

    try do
      start = System.os_time(:millisecond) - 600_000
      frame_us = div(1_000_000, 15)

      frames =
        Neptunus.Test.Dives.h264(90, fps: 15, gop: 15)
        |> Enum.with_index()
        |> Enum.map(fn {au, i} ->
          {start * 1000 + i * frame_us, Neptunus.Test.Dives.keyframe?(au), au}
        end)

      telemetry =
        for i <- 0..129 do
          {start - 200 + i * 50, "telemetry",
           %{
             t: i * 0.05,
             estimate: %{depth: 3.0 * i / 129, heading: 1.0 + i / 200},
             measurement: %{depth: 3.0 * i / 129, heading: 1.0 + i / 200},
             thrusters: %{port: 0.1, vertical: 0.3, starboard: 0.1}
           }}
        end

      events = [
        {start + 1_000, "helm", %{state: "piloted", pilot: %{name: "ada", role: "pilot"}}},
        {start + 2_500, "stopped", %{reason: "deadman"}},
        {start + 3_000, "log",
         %{category: "autopilot", level: "info", message: "depth hold 2 m", at: start + 3_000}},
        {start + 4_000, "snapshot", %{name: "x.jpg", depth: 2.0, heading: 1.0}}
      ]

      name = Calendar.strftime(DateTime.from_unix!(start, :millisecond), "%Y%m%d-%H%M%SZ") <> "-1"

      Neptunus.Test.Dives.write!(
        dir,
        "neptunus-1",
        name,
        Enum.sort_by(telemetry ++ events, &elem(&1, 0)),
        frames,
        started_at: start - 200,
        info: %{codec: "h264", generation: 1, width: 160, height: 120, fps: 15}
      )

      output =
        node_suite!("test/e2e/replay.e2e.mjs", [
          {"E2E_DIVE", name},
          {"E2E_FRAMES_US", Enum.map_join(frames, ",", &elem(&1, 0))},
          {"E2E_EVENTS_MS", Enum.map_join(events, ",", &elem(&1, 0))}
        ])

      # the figures of how closely the picture follows the cursor while playing (printed, not judged)
      for line <- String.split(output, "\n"), line =~ "# sync", do: IO.puts(String.trim(line))
    after
      File.rm_rf!(dir)
    end
  end

  test "the video socket in secure mode: refused without a login, an observer watches (Chromium)" do
    logins = %{"e2e-olga" => "olga pw"}
    hash = NeptunusWeb.Auth.Password.hash("olga pw", iterations: 1000)

    NeptunusWeb.Test.Wire.settings!(
      auth: %{
        mode: :secure,
        secret: Base.encode64(:crypto.strong_rand_bytes(32)),
        users: %{"e2e-olga" => %{name: "e2e-olga", role: :observer, hash: hash}},
        anonymous_observers: false,
        origins: []
      }
    )

    NeptunusWeb.Auth.RateLimit.reset()
    id = "z-e2e-secure-video-#{System.unique_integer([:positive])}"
    {:ok, sim} = Neptunus.Camera.Source.parse("sim")
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, camera: sim})

    try do
      node_suite!("test/e2e/video_secure.e2e.mjs", [
        {"E2E_VIDEO_VEHICLE", id},
        {"NEPTUNUS_E2E_LOGINS", :jiffy.encode(logins) |> IO.iodata_to_binary()}
      ])
    after
      Neptunus.Fleet.stop_vehicle(id)
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
