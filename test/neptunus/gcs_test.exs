defmodule Neptunus.GCSTest do
  # Ground stations against a running node: the endpoints, sessions and sources with a
  # simulated vehicle, spoken to by a MAVLink client written with the project's codec
  # (test/support/gcs_client.ex). The real clients (pymavlink, MAVProxy) are in
  # test/neptunus_web/gcs_external_test.exs.
  use ExUnit.Case, async: false

  alias Neptunus.GCS.{Endpoint, Link}
  alias Neptunus.Protocol.MAVLink.Signing
  alias Neptunus.Test.GCSClient
  alias Neptunus.Vehicle.{Control, Helm}

  @moduletag :capture_log
  @sysid 7
  @key Signing.key_from_passphrase("gcs test passphrase")
  @other Signing.key_from_passphrase("another ground station")

  setup do
    id = "gcs-#{System.unique_integer([:positive])}"
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    {:ok, id: id}
  end

  defp endpoint(kind, opts \\ []) do
    %{
      kind: kind,
      address: {127, 0, 0, 1},
      port: Keyword.get(opts, :port, 0),
      loopback: Keyword.get(opts, :loopback, true),
      gcs: Keyword.get(opts, :gcs),
      spec: "#{kind} (test)",
      link_id: Keyword.get(opts, :link_id, 0)
    }
  end

  defp serve!(id, endpoints, opts \\ []) do
    gcs = %{
      endpoints: endpoints,
      systems: %{id => @sysid},
      keys: %{
        "qgc" => %{name: "qgc", role: :pilot, key: @key},
        "other" => %{name: "other", role: :observer, key: @other}
      },
      trusted: Keyword.get(opts, :trusted, []),
      unsigned: Keyword.get(opts, :unsigned, :none),
      mode: :local
    }

    start_supervised!(
      {Neptunus.GCS,
       gcs: gcs,
       vehicles: [%{id: id, board: :simulated}],
       timeout_ms: Keyword.get(opts, :timeout_ms, 5_000)}
    )

    for e <- endpoints, do: Endpoint.stats(Endpoint.name(e.link_id)).port
  end

  defp heartbeat!(gcs, opts \\ []),
    do:
      GCSClient.send!(
        gcs,
        :heartbeat,
        %{type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4},
        opts
      )

  defp command!(gcs, command, params),
    do: GCSClient.send!(gcs, :command_long, GCSClient.command_long(@sysid, command, params))

  defp ack!(gcs, command, ms \\ 3_000),
    do:
      GCSClient.expect!(gcs, &(&1.name == :command_ack and &1.fields.command == command), ms).fields.result

  defp manual!(gcs, x, z \\ 500, r \\ 0),
    do:
      GCSClient.send!(gcs, :manual_control, %{target: @sysid, x: x, y: 0, z: z, r: r, buttons: 0})

  defp take_helm!(gcs) do
    command!(gcs, 32_100, [0, 1, 0, 10])
    assert ack!(gcs, 32_100) == 0
    GCSClient.expect!(gcs, &(&1.name == :control_status and &1.fields.sysid_in_control == 255))
  end

  # waits until `fun` holds (polling a process' state, never sleeping a fixed time)
  defp until(fun, what, tries \\ 100) do
    cond do
      fun.() -> :ok
      tries == 0 -> flunk("timed out waiting for #{what}")
      true -> Process.sleep(30) && until(fun, what, tries - 1)
    end
  end

  defp browser_party do
    me = self()

    %{
      id: "browser-#{System.unique_integer([:positive])}",
      name: "ada",
      role: :pilot,
      pid: me,
      notify: fn e, p -> send(me, {:helm, e, p}) end
    }
  end

  test "a ground station sees the vehicle as a submarine and its telemetry", %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)])
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)

    hb = GCSClient.expect!(gcs, &(&1.name == :heartbeat))
    assert %{system: @sysid, component: 1, fields: %{type: 12, autopilot: 0}} = hb

    for name <- [
          :attitude,
          :vfr_hud,
          :sys_status,
          :scaled_pressure,
          :servo_output_raw,
          :named_value_float,
          :system_time,
          :control_status,
          :local_position_ned
        ],
        do: GCSClient.expect!(gcs, &(&1.name == name))

    command!(gcs, 512, [148])
    assert ack!(gcs, 512) == 0

    assert %{fields: %{capabilities: caps}} =
             GCSClient.expect!(gcs, &(&1.name == :autopilot_version))

    assert Bitwise.band(caps, 524_288) != 0

    # a message turned off stops coming; back to the default, it comes again
    command!(gcs, 511, [30, -1])
    assert ack!(gcs, 511) == 0
    GCSClient.flush(gcs)
    # the schedule is the session's: after a tick nothing more is due
    refute GCSClient.arrives?(gcs, &(&1.name == :attitude), 500)
    command!(gcs, 511, [30, 0])
    GCSClient.expect!(gcs, &(&1.name == :attitude))
  end

  test "the helm as for a browser: request, fly with MANUAL_CONTROL, silence stops the vehicle",
       %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)])
    Neptunus.PubSub.subscribe("vehicle:" <> id)
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)
    GCSClient.expect!(gcs, &(&1.name == :heartbeat))

    # not the pilot: the stick is ignored and counted
    manual!(gcs, 600)
    [link] = Endpoint.stats(Endpoint.name(0)).sessions
    until(fn -> Link.stats(link)[:manual_ignored] == 1 end, "the ignored stick counted")
    assert Control.status(id).command.surge == 0.0

    take_helm!(gcs)
    assert %{pilot: %{name: "gcs-255 (GCS 255)"}} = Helm.status(id)

    manual!(gcs, 600, 250, 0)

    until(
      fn -> Control.status(id).command == %{surge: 0.6, heave: 0.5, yaw: 0.0} end,
      "the stick applied"
    )

    # silence: the deadman stops it, as for a browser
    assert_receive {:pubsub, _, "stopped", %{reason: "deadman"}}, 3_000
    assert Control.status(id).command.surge == 0.0
    # the same stick again is no fresh input: the vehicle stays stopped
    manual!(gcs, 600, 250, 0)
    manual!(gcs, 600, 250, 0)
    Process.sleep(200)
    assert Control.status(id).command.surge == 0.0
    # a fresh one moves it (the ground station goes on sending it, as they do)
    until(
      fn -> manual!(gcs, 300) && Control.status(id).command.surge == 0.3 end,
      "fresh input after the deadman"
    )
  end

  test "a browser pilot sees the ground station's request and allows it", %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)])
    party = browser_party()
    assert {:ok, %{status: "granted"}} = Helm.request_control(id, party)

    gcs = GCSClient.start!(port)
    heartbeat!(gcs)
    command!(gcs, 32_100, [0, 1, 0, 10])
    assert ack!(gcs, 32_100) == 5
    assert_receive {:helm, "control_request", %{from: %{name: "gcs-255 (GCS 255)"}}}, 3_000

    assert {:ok, _} = Helm.answer_request(id, party, true)
    assert_receive {:helm, "control_lost", %{reason: "control_transferred"}}
    assert ack!(gcs, 32_100) == 0
    GCSClient.expect!(gcs, &(&1.name == :control_status and &1.fields.sysid_in_control == 255))
  end

  test "a pilot ground station is asked for its helm and gives it", %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)])
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)
    take_helm!(gcs)

    party = browser_party()
    assert {:ok, %{status: "pending"}} = Helm.request_control(id, party)

    ask = GCSClient.expect!(gcs, &(&1.name == :command_long and &1.fields.command == 32_100))
    assert %{param1: 0.0, param2: 1.0, param4: 10.0, target_system: 255} = ask.fields

    # allow takeover: the helm goes to the browser
    command!(gcs, 32_100, [0, 1, 1])
    assert_receive {:helm, "control_granted", %{epoch: _}}, 3_000
    assert ack!(gcs, 32_100) == 0
    GCSClient.expect!(gcs, &(&1.name == :statustext and &1.fields.text =~ "helm lost"))
  end

  test "commands: arm (the helm), mode, lights and tilt; parameters read and set through control",
       %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)])
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)

    command!(gcs, 400, [1])
    assert ack!(gcs, 400) == 2
    take_helm!(gcs)
    # a pilot streams its stick (a joystick at rest), which feeds the deadman
    GCSClient.stream!(
      gcs,
      :manual_control,
      %{target: @sysid, x: 0, y: 0, z: 500, r: 0, buttons: 0},
      100
    )

    command!(gcs, 400, [1])
    assert ack!(gcs, 400) == 0

    GCSClient.expect!(
      gcs,
      &(&1.name == :heartbeat and Bitwise.band(&1.fields.base_mode, 128) != 0)
    )

    command!(gcs, 183, [9, 1900])
    assert ack!(gcs, 183) == 0
    assert Control.status(id).lights == 255
    command!(gcs, 205, [-20])
    assert ack!(gcs, 205) == 0
    assert_in_delta Control.status(id).tilt, -20 * :math.pi() / 180, 1.0e-6

    # STABILIZE: heading hold (once the heading is valid)
    until(
      fn ->
        match?(
          %{estimate: %{heading: h}} when is_number(h),
          Neptunus.Vehicle.Telemetry.latest(id)
        )
      end,
      "a heading"
    )

    command!(gcs, 176, [1, 0])
    assert ack!(gcs, 176) == 0
    assert Control.status(id).autopilot.heading != nil
    GCSClient.expect!(gcs, &(&1.name == :heartbeat and &1.fields.custom_mode == 0))

    GCSClient.send!(gcs, :param_request_list, %{target_system: @sysid, target_component: 1})
    first = GCSClient.expect!(gcs, &(&1.name == :param_value))
    assert first.fields.param_count == 16

    GCSClient.send!(gcs, :param_set, %{
      target_system: @sysid,
      target_component: 1,
      param_id: "PILOT_GAIN",
      param_value: 0.75,
      param_type: 9
    })

    assert %{fields: %{param_value: 0.75}} =
             GCSClient.expect!(
               gcs,
               &(&1.name == :param_value and &1.fields.param_id == "PILOT_GAIN" and
                   &1.fields.param_value == 0.75)
             )

    assert Control.status(id).gain == 0.75

    # refused: the value in force comes back, and why
    GCSClient.send!(gcs, :param_set, %{
      target_system: @sysid,
      target_component: 1,
      param_id: "PILOT_GAIN",
      param_value: 3.0,
      param_type: 9
    })

    assert %{fields: %{param_value: 0.75}} =
             GCSClient.expect!(
               gcs,
               &(&1.name == :param_value and &1.fields.param_id == "PILOT_GAIN")
             )

    GCSClient.expect!(gcs, &(&1.name == :statustext and &1.fields.text =~ "PILOT_GAIN refused"))
  end

  test "beyond loopback: unsigned ground stations get nothing; a key's get signed telemetry; replays and wrong keys are dropped",
       %{id: id} do
    [port] = serve!(id, [endpoint(:udpin, loopback: false)])

    unsigned = GCSClient.start!(port)
    heartbeat!(unsigned)
    refute GCSClient.arrives?(unsigned, fn _ -> true end, 800)
    assert %{counters: %{not_admitted: n}, sessions: []} = Endpoint.stats(Endpoint.name(0))
    assert n >= 1

    wrong = GCSClient.start!(port, key: Signing.key_from_passphrase("a guess"))
    heartbeat!(wrong)
    refute GCSClient.arrives?(wrong, fn _ -> true end, 500)

    signed = GCSClient.start!(port, key: @key)
    heartbeat!(signed)
    hb = GCSClient.expect!(signed, &(&1.name == :heartbeat))
    assert Signing.verify(hb, @key)

    # its session accepts nothing unsigned or signed otherwise, and no replay
    frame =
      GCSClient.frame!(signed, :command_long, %{
        target_system: @sysid,
        target_component: 1,
        command: 32_100,
        confirmation: 0,
        param1: 0.0,
        param2: 1.0,
        param3: 0.0,
        param4: 10.0,
        param5: 0.0,
        param6: 0.0,
        param7: 0.0
      })

    GCSClient.send_raw!(signed, frame)
    assert ack!(signed, 32_100) == 0
    GCSClient.send_raw!(signed, frame)
    heartbeat!(signed, key: nil)
    heartbeat!(signed, key: @other)
    [link] = Endpoint.stats(Endpoint.name(0)).sessions

    until(
      fn -> match?(%{replayed: 1, unsigned: 1, bad_signature: 1}, Link.stats(link)) end,
      "the drops counted"
    )

    refute GCSClient.arrives?(signed, &(&1.name == :command_ack), 300)
  end

  test "unsigned ground stations beyond loopback may watch when configured; they still fly nothing",
       %{id: id} do
    [port] = serve!(id, [endpoint(:udpin, loopback: false)], unsigned: :watch)
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)
    GCSClient.expect!(gcs, &(&1.name == :attitude))
    command!(gcs, 32_100, [0, 1])
    refute GCSClient.arrives?(gcs, &(&1.name == :command_ack), 500)
    assert Helm.status(id).pilot == nil
  end

  test "malformed, truncated, oversized and flooding input: counted, never a crash; the pilot flies on",
       %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)])
    pilot = GCSClient.start!(port)
    heartbeat!(pilot)
    take_helm!(pilot)
    [link] = Endpoint.stats(Endpoint.name(0)).sessions

    GCSClient.send_raw!(pilot, :crypto.strong_rand_bytes(200))

    GCSClient.send_raw!(
      pilot,
      binary_part(
        GCSClient.frame!(pilot, :heartbeat, %{
          type: 6,
          autopilot: 8,
          base_mode: 0,
          custom_mode: 0,
          system_status: 4
        }),
        0,
        7
      )
    )

    GCSClient.send_raw!(pilot, :binary.copy(<<0xFD>>, 5000))

    flood = GCSClient.start!(port, sysid: 200)

    frame =
      GCSClient.frame!(flood, :heartbeat, %{
        type: 6,
        autopilot: 8,
        base_mode: 0,
        custom_mode: 0,
        system_status: 4
      })

    GCSClient.send_raw!(flood, frame)

    GCSClient.stream!(
      pilot,
      :manual_control,
      %{target: @sysid, x: 400, y: 0, z: 500, r: 0, buttons: 0},
      100
    )

    until(
      fn -> length(Endpoint.stats(Endpoint.name(0)).sessions) == 2 end,
      "the flooder's session"
    )

    [flooder] = Endpoint.stats(Endpoint.name(0)).sessions -- [link]

    # it floods until its session counts it (however slowly a busy machine handles a burst)
    until(
      fn ->
        for _ <- 1..10, do: GCSClient.send_raw!(flood, :binary.copy(frame, 40))
        Map.get(Link.stats(flooder), :flood, 0) > 0
      end,
      "the flood counted"
    )

    until(
      fn -> Control.status(id).command.surge == 0.4 end,
      "the pilot's stick through the flood"
    )

    assert Process.alive?(link)
    stats = Link.stats(link)
    assert stats.garbage_bytes + Map.get(stats, :truncated, 0) > 0 and stats.oversized == 1
  end

  test "a pilot ground station that goes away frees the helm (its session ends)", %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)], timeout_ms: 1_000)
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)
    take_helm!(gcs)
    [link] = Endpoint.stats(Endpoint.name(0)).sessions
    ref = Process.monitor(link)
    assert_receive {:DOWN, ^ref, :process, _, :normal}, 5_000
    until(fn -> Helm.status(id).pilot == nil end, "the helm freed")
  end

  test "a trusted ground station takes a free helm with its stick", %{id: id} do
    [port] = serve!(id, [endpoint(:udpin)], trusted: [255])
    gcs = GCSClient.start!(port)
    heartbeat!(gcs)
    GCSClient.expect!(gcs, &(&1.name == :heartbeat))
    manual!(gcs, 0)
    GCSClient.expect!(gcs, &(&1.name == :control_status and &1.fields.sysid_in_control == 255))
    manual!(gcs, 500)
    until(fn -> Control.status(id).command.surge == 0.5 end, "the trusted stick")
  end

  test "tcpin: a connection is a session; udpout: telemetry pushed to the configured ground station",
       %{id: id} do
    {:ok, listen} = :gen_udp.open(0, [:binary, ip: {127, 0, 0, 1}])
    {:ok, peer_port} = :inet.port(listen)
    :gen_udp.close(listen)
    [tcp_port, _] = serve!(id, [endpoint(:tcpin), endpoint(:udpout, port: peer_port, link_id: 1)])

    pushed = GCSClient.start!(peer_port + 0, listen: peer_port)
    GCSClient.expect!(pushed, &(&1.name == :heartbeat and &1.system == @sysid))

    {:ok, socket} = :gen_tcp.connect({127, 0, 0, 1}, tcp_port, [:binary, active: false])

    {:ok, frame} =
      Neptunus.Protocol.MAVLink.encode(
        :heartbeat,
        %{type: 6, autopilot: 8, base_mode: 0, custom_mode: 0, system_status: 4},
        %{system: 255, component: 190, seq: 0}
      )

    :ok = :gen_tcp.send(socket, frame)
    assert {:ok, data} = :gen_tcp.recv(socket, 0, 3_000)
    {_, messages, _} = Neptunus.Protocol.MAVLink.decode(Neptunus.Protocol.MAVLink.new(), data)
    assert Enum.all?(messages, &(&1.system == @sysid))
    :gen_tcp.close(socket)
  end
end
