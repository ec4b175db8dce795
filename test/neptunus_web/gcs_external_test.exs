defmodule NeptunusWeb.GCSExternalTest do
  # Real ground stations against the node's MAVLink endpoint: pymavlink
  # (test/support/gcs_pymavlink.py) and MAVProxy with a browser pilot in Chromium
  # (test/e2e/gcs.e2e.mjs), both from PyPI in the project's .venv (`make setup`).
  use ExUnit.Case, async: false

  alias Neptunus.GCS.{Endpoint, Link}
  alias Neptunus.Protocol.MAVLink.Signing
  alias Neptunus.Test.PyMAVLink
  alias Neptunus.Vehicle.Helm

  @moduletag :external
  @moduletag :capture_log
  @moduletag timeout: 240_000

  @root Path.expand("../..", __DIR__)
  @sysid 3
  # one word: MAVProxy's `signing key` takes its first argument
  @passphrase "neptunus-e2e-passphrase"

  # a test's `@tag vehicle: %{...}` is merged into its simulated vehicle (a model, position sources)
  setup ctx do
    id = "gcs-e2e-#{System.unique_integer([:positive])}"
    vehicle = Map.merge(%{id: id, board: :simulated}, Map.get(ctx, :vehicle, %{}))
    {:ok, _} = Neptunus.Fleet.start_vehicle(vehicle)
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)

    endpoint = fn kind, address, loopback, link_id ->
      %{
        kind: kind,
        address: address,
        port: 0,
        loopback: loopback,
        gcs: nil,
        spec: "#{kind}:#{:inet.ntoa(address)}:0",
        link_id: link_id
      }
    end

    gcs = %{
      # loopback: anyone on this computer; 0.0.0.0: beyond it, signed only
      endpoints: [
        endpoint.(:udpin, {127, 0, 0, 1}, true, 0),
        endpoint.(:udpin, {0, 0, 0, 0}, false, 1),
        endpoint.(:tcpin, {127, 0, 0, 1}, true, 2)
      ],
      systems: %{id => @sysid},
      keys: %{"mp" => %{name: "mp", role: :pilot, key: Signing.key_from_passphrase(@passphrase)}},
      trusted: [],
      unsigned: :none,
      mode: :local
    }

    start_supervised!({Neptunus.GCS, gcs: gcs, vehicles: [vehicle]})
    [loopback, far, tcp] = for link <- [0, 1, 2], do: Endpoint.stats(Endpoint.name(link)).port
    {:ok, id: id, loopback: loopback, far: far, tcp: tcp}
  end

  defp port_output(port, acc \\ "") do
    receive do
      {^port, {:data, data}} -> port_output(port, acc <> data)
    after
      0 -> acc
    end
  end

  defp python!(args) do
    {output, status} =
      System.cmd(PyMAVLink.python!(), [Path.join(@root, "test/support/gcs_pymavlink.py") | args],
        env: [{"MAVLINK20", "1"}],
        stderr_to_stdout: true
      )

    assert status == 0, "gcs_pymavlink.py #{Enum.join(args, " ")} failed:\n#{output}"
    :jiffy.decode(output, [:return_maps])
  end

  for transport <- [:udpin, :tcpin] do
    test "pymavlink over #{transport}: telemetry, an interval, AUTOPILOT_VERSION, parameters, the helm, MANUAL_CONTROL, silence, disarm",
         %{id: id} = context do
      port =
        case unquote(transport) do
          :udpin -> "#{context.loopback}"
          :tcpin -> "tcp:#{context.tcp}"
        end

      fly(id, port)
    end
  end

  defp fly(id, port) do
    Neptunus.PubSub.subscribe("vehicle:" <> id)
    report = python!(["fly", port, "#{@sysid}"])

    assert %{"type" => 12, "autopilot" => 0} = report["heartbeat"]

    for name <-
          ~w(ATTITUDE VFR_HUD SYS_STATUS SCALED_PRESSURE SERVO_OUTPUT_RAW NAMED_VALUE_FLOAT SYSTEM_TIME),
        do: assert(report["seen"][name] > 0, "#{name} not seen: #{inspect(report["seen"])}")

    # a vehicle without position sources has no position: the simulator's truth is not one
    refute Map.has_key?(report["seen"], "LOCAL_POSITION_NED")

    # ATTITUDE and VFR_HUD at about 10 Hz, SYS_STATUS about 2 Hz over 3 s (ranges wide: a busy machine)
    assert report["seen"]["VFR_HUD"] >= 15
    assert report["seen"]["SYS_STATUS"] in 3..9

    assert report["interval_ack"] == 0
    assert report["autopilot_version_ack"] == 0
    assert is_integer(report["capabilities"]) and report["capabilities"] > 0
    assert map_size(report["params"]) == 16 and report["params"]["PILOT_GAIN"] == 0.5
    # refused (not the pilot): the answer is the value kept
    assert report["lights_refused"] == report["params"]["LIGHTS"]
    assert Neptunus.Vehicle.Control.status(id).lights == round(report["params"]["LIGHTS"])
    # its stick moved nothing before it had the helm
    assert [_ | _] = report["servo_without_helm"]
    assert Enum.all?(report["servo_without_helm"], &(&1 == [1500, 1500, 1500]))
    assert report["helm_ack"] == 0
    assert report["arm_ack"] == 0, inspect(report)
    assert report["armed_heartbeat"], inspect(report)
    # forward on port and starboard, down on the vertical (go() order: port, vertical, starboard)
    assert [port_us, vertical_us, starboard_us] = report["servo"]
    assert port_us > 1500 and starboard_us > 1500 and vertical_us != 1500
    assert report["deadman_text"] =~ "stopped: deadman"
    assert_received {:pubsub, _, "stopped", %{reason: "deadman"}}
    # a simulated board has no arming of its own: it is armed while a pilot holds the helm,
    # and disarming gives the helm up
    assert report["disarm_ack"] == 0 and report["disarmed_heartbeat"]
    assert_received {:pubsub, _, "helm", %{pilot: %{name: "gcs-255 (GCS 255)"}}}
    assert Helm.status(id).pilot == nil
  end

  describe "MANUAL_CONTROL's y (lateral)" do
    @tag vehicle: %{sim: [vehicle: "neptunus-sway"]}
    test "is sway on a vehicle that can sway (a simulated neptunus-sway): its lateral thruster pushes it to starboard",
         %{id: id, loopback: port} do
      assert :sway in Neptunus.Vehicle.Board.capabilities(id).axes
      stick!(id, port, 0, 800)

      # the pilot's command carried sway; the vehicle moved to starboard under it
      assert_received {:pubsub, _, "telemetry", %{command: %{sway: 0.8, surge: +0.0}}}
      assert telemetry_seen(fn t -> t.sim.v > 0.01 end), "the vehicle never moved to starboard"
    end

    test "is ignored on a vehicle without sway (the three-thruster vehicle): the rest of the stick flies",
         %{id: id, loopback: port} do
      refute :sway in Neptunus.Vehicle.Board.capabilities(id).axes
      stick!(id, port, 300, 800)

      # not refused (the vehicle has no sway): the surge flew, without sway
      assert_received {:pubsub, _, "telemetry", %{command: %{surge: 0.3} = command}}
      refute Map.has_key?(command, :sway)
      refute telemetry_seen(fn t -> is_map(t.command) and Map.has_key?(t.command, :sway) end)
    end
  end

  @tag vehicle: %{position: [{:sim_dvl, []}, {:sim_usbl, []}]}
  test "pymavlink sees LOCAL_POSITION_NED from the position estimate of a vehicle with a DVL and a USBL; its interval is honoured",
       %{id: id, loopback: port} do
    Neptunus.PubSub.subscribe("vehicle:" <> id)
    # the simulated DVL and USBL report through the real drivers: a valid position
    assert_receive {:pubsub, _, "telemetry", %{position: %{valid: true}}}, 60_000
    report = python!(["position", "#{port}", "#{@sysid}"])
    positions = report["first"] ++ report["at_5hz"] ++ report["requested"]
    assert [_ | _] = report["first"], inspect(report)

    # each one the estimate of a telemetry broadcast (float32 on the wire), never the truth
    estimates =
      for {:pubsub, _, "telemetry", %{position: %{valid: true} = p}} <- mailbox(),
          do: {p.north, p.east}

    for p <- positions do
      assert Enum.any?(estimates, fn {n, e} ->
               abs(n - p["x"]) < 1.0e-3 and abs(e - p["y"]) < 1.0e-3
             end),
             "#{inspect(p)} is no estimate the vehicle broadcast"

      assert p["z"] > -0.5
    end

    assert report["interval_ack"] == 0 and report["interval_us"] == 200_000
    assert [_ | _] = report["at_5hz"]
    assert report["off_ack"] == 0 and report["while_off"] == []
    assert report["request_ack"] == 0
    assert [_] = report["requested"]
    # no geodetic origin: no GLOBAL_POSITION_INT (docs/MAVLINK.md)
    assert report["global_position_int"] == 0
  end

  defp mailbox(acc \\ []) do
    receive do
      message -> mailbox([message | acc])
    after
      0 -> Enum.reverse(acc)
    end
  end

  # the helm, then MANUAL_CONTROL x, y from pymavlink for 2 s, the vehicle's broadcasts
  # meanwhile in the mailbox
  defp stick!(id, port, x, y) do
    Neptunus.PubSub.subscribe("vehicle:" <> id)
    report = python!(["stick", "#{port}", "#{@sysid}", "#{x}", "#{y}"])
    assert %{"heartbeat" => true, "helm_ack" => 0} = report
  end

  # whether a telemetry broadcast already received satisfies `fun` (each is looked at once)
  defp telemetry_seen(fun) do
    receive do
      {:pubsub, _, "telemetry", t} -> fun.(t) or telemetry_seen(fun)
    after
      0 -> false
    end
  end

  test "beyond loopback: an unsigned ground station sees nothing; one with the key gets signed telemetry",
       %{far: port} do
    unsigned = python!(["watch", "#{port}", "3"])
    assert unsigned["messages"] == %{}, inspect(unsigned)

    wrong = python!(["watch", "#{port}", "3", "a wrong passphrase"])
    assert wrong["messages"] == %{}, inspect(wrong)

    signed = python!(["watch", "#{port}", "3", @passphrase])
    assert signed["messages"]["HEARTBEAT"] >= 2
    assert signed["systems"] == [@sysid]
    assert signed["goodsig"] > 10 and signed["badsig"] == 0

    %{counters: counters} = Endpoint.stats(Endpoint.name(1))
    assert counters[:not_admitted] >= 4
  end

  test "beyond loopback: MAVProxy signs with `signing key` and signs what it forwards for an unsigned tool behind it",
       %{far: port} do
    mavproxy = Path.join(@root, ".venv/bin/mavproxy.py")
    unless File.exists?(mavproxy), do: flunk("#{mavproxy} is missing: run `make setup`")
    {:ok, probe} = :gen_udp.open(0, ip: {127, 0, 0, 1})
    {:ok, out} = :inet.port(probe)
    :ok = :gen_udp.close(probe)

    # docs/MAVLINK.md, "Signing": the tool that does not sign talks to MAVProxy, MAVProxy to the node
    bridge =
      Port.open({:spawn_executable, mavproxy}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        args: [
          "--master=udpout:127.0.0.1:#{port}",
          "--out=udpout:127.0.0.1:#{out}",
          "--no-state",
          "--default-modules=link,signing",
          "--cmd=signing key #{@passphrase}"
        ],
        cd: System.tmp_dir!(),
        env: [{~c"MAVLINK20", ~c"1"}, {~c"PYTHONUNBUFFERED", ~c"1"}]
      ])

    {:os_pid, os_pid} = Port.info(bridge, :os_pid)
    on_exit(fn -> System.cmd("kill", ["-9", "#{os_pid}"], stderr_to_stdout: true) end)

    report = python!(["behind", "#{out}", "#{@sysid}", "20"])
    said = port_output(bridge)
    assert %{"type" => 12} = report["heartbeat"], "#{inspect(report)}; MAVProxy said:\n#{said}"
    assert report["params"] == 16, "#{inspect(report)}; MAVProxy said:\n#{said}"
    %{sessions: [session]} = Endpoint.stats(Endpoint.name(1))
    assert Link.stats(session)[:messages] > 0
  end

  test "MAVProxy and a browser pilot (Chromium): parameters, the dive, the helm given, arm, drive, silence stops",
       %{id: id, loopback: port} do
    unless File.exists?(Path.join(@root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    mavproxy = Path.join(@root, ".venv/bin/mavproxy.py")
    unless File.exists?(mavproxy), do: flunk("#{mavproxy} is missing: run `make setup`")
    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")
    url = "http://127.0.0.1:#{Application.fetch_env!(:neptunus, :endpoint).port}"

    {output, status} =
      System.cmd(node, ["--test", "--test-reporter=spec", "test/e2e/gcs.e2e.mjs"],
        cd: @root,
        env: [
          {"NEPTUNUS_URL", url},
          {"E2E_GCS_VEHICLE", id},
          {"E2E_GCS_PORT", "#{port}"},
          {"MAVPROXY", mavproxy}
        ],
        stderr_to_stdout: true
      )

    assert status == 0, "gcs.e2e.mjs failed (exit #{status}):\n#{output}"
    refute output =~ ~r/fail [1-9]/
    assert Neptunus.Vehicle.Control.status(id).lights == 40
  end
end
