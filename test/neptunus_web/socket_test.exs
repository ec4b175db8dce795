defmodule NeptunusWeb.SocketTest do
  # Wire-level tests against the running endpoint, with a real WebSocket client.
  use ExUnit.Case, async: false

  alias NeptunusWeb.Test.WSClient

  @moduletag :capture_log

  setup do
    id = "wire-#{System.unique_integer([:positive])}"
    {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated})
    on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
    {:ok, id: id, topic: "vehicle:" <> id}
  end

  defp port, do: Application.fetch_env!(:neptunus, :endpoint).port

  defp connect!(name \\ "tester") do
    {:ok, ws} = WSClient.connect(port(), "/socket/websocket?vsn=2.0.0&name=#{URI.encode(name)}")
    ws
  end

  defp reply_to(ws, ref), do: WSClient.recv_until(ws, &match?([_, ^ref, _, "phx_reply", _], &1))

  defp push_and_reply(ws, join_ref, topic, event, payload) do
    ref = WSClient.unique_ref()
    WSClient.push(ws, join_ref, ref, topic, event, payload)

    [^join_ref, ^ref, ^topic, "phx_reply", %{"status" => status, "response" => response}] =
      reply_to(ws, ref)

    {status, response}
  end

  defp join!(ws, topic) do
    join_ref = WSClient.unique_ref()
    {:ok, response} = WSClient.join(ws, topic, %{}, join_ref)
    {join_ref, response}
  end

  defp thrust(s), do: %{"mode" => "motion", "surge" => s, "heave" => 0, "yaw" => 0}

  describe "upgrade" do
    test "refuses a missing or wrong protocol version" do
      assert {:error, {:http_status, 400, %{body: body}}} =
               WSClient.connect(port(), "/socket/websocket")

      assert body =~ "vsn=2.0.0"

      assert {:error, {:http_status, 400, _}} =
               WSClient.connect(port(), "/socket/websocket?vsn=1.0.0")
    end

    test "refuses other socket paths" do
      assert {:error, {:http_status, 404, _}} =
               WSClient.connect(port(), "/socket/longpoll?vsn=2.0.0")
    end
  end

  test "heartbeat is answered with the same ref" do
    ws = connect!()
    WSClient.push(ws, nil, "hb1", "phoenix", "heartbeat", %{})

    assert [nil, "hb1", "phoenix", "phx_reply", %{"status" => "ok", "response" => %{}}] =
             WSClient.recv_frame(ws)
  end

  test "a silent connection is closed; heartbeats keep it open" do
    # a timeout far beyond the heartbeats' 100 ms, so a busy machine's pause in them does not
    # reach it
    NeptunusWeb.Test.Wire.settings!(idle_timeout_ms: 2_000)
    lively = connect!()
    silent = connect!()

    spawn_link(fn ->
      Stream.iterate(1, &(&1 + 1))
      |> Enum.each(fn i ->
        WSClient.push(lively, nil, "hb#{i}", "phoenix", "heartbeat", %{})
        Process.sleep(100)
      end)
    end)

    # the silent one is closed; the lively one, connected before it and so silent longer had
    # it not heartbeated, is still served
    assert_receive {:ws, ^silent, {:close, 1000, "heartbeat timeout"}}
    refute_received {:ws, ^lively, {:close, _, _}}
    WSClient.push(lively, nil, "after", "phoenix", "heartbeat", %{})

    assert [_, "after", "phoenix", "phx_reply", %{"status" => "ok"}] =
             WSClient.recv_until(lively, &match?([_, "after" | _], &1))
  end

  test "a client's close is echoed (clean close, not 1006)" do
    ws = connect!()
    WSClient.close(ws, 1001, "going away")
    assert_receive {:ws, ^ws, {:close, 1001, _}}
    assert_receive {:ws, ^ws, :closed}
  end

  test "fleet lists the vehicles", %{id: id} do
    ws = connect!()
    {_, %{"vehicles" => vehicles}} = join!(ws, "fleet")
    node = Atom.to_string(node())

    for vid <- [id, "neptunus-1"] do
      assert %{"board" => "simulated", "node" => ^node, "status" => "up", "helm" => "free"} =
               Enum.find(vehicles, &(&1["id"] == vid))
    end
  end

  test "vehicle join: snapshot, then presence_state with ourselves, then telemetry", ctx do
    ws = connect!("Ada")
    {join_ref, snapshot} = join!(ws, ctx.topic)
    assert %{"vehicle" => %{"id" => id}, "pilot" => nil, "control" => control} = snapshot
    assert id == ctx.id
    assert %{"gain" => 0.5, "mode" => "motion", "command" => %{"surge" => +0.0}} = control
    assert Map.has_key?(snapshot, "telemetry")

    assert %{"state" => "free", "pilot" => nil, "epoch" => epoch, "deadman_ms" => 500} =
             snapshot["helm"]

    assert is_integer(epoch) and epoch >= 0

    assert %{"name" => "Ada", "role" => "pilot", "mode" => "local", "id" => conn} =
             snapshot["session"]

    assert [^join_ref, nil, _, "presence_state", %{"Ada" => %{"metas" => [meta]}}] =
             WSClient.recv_until(ws, &match?([_, _, _, "presence_state", _], &1))

    assert is_binary(meta["phx_ref"])
    assert %{"name" => "Ada", "role" => "pilot", "pilot" => false, "conn" => ^conn} = meta
    assert is_integer(meta["since"])

    assert [nil, nil, _, "telemetry", telemetry] =
             WSClient.recv_until(ws, &match?([_, _, _, "telemetry", _], &1))

    for key <- ~w(t sent_at measurement sim command thrusters),
        do: assert(Map.has_key?(telemetry, key))
  end

  test "unknown topics and vehicles are refused with a reason" do
    ws = connect!()
    assert {:error, %{"reason" => "unmatched topic"}} = WSClient.join(ws, "room:lobby")
    assert {:error, %{"reason" => "unknown vehicle: nope"}} = WSClient.join(ws, "vehicle:nope")
  end

  test "pushes to a topic not joined get unmatched topic", %{topic: topic} do
    ws = connect!()

    assert {"error", %{"reason" => "unmatched topic"}} =
             push_and_reply(ws, "9", topic, "thrust", thrust(1))
  end

  test "malformed frames get a readable error and the connection stays up", %{topic: topic} do
    ws = connect!()
    WSClient.send_text(ws, "{not json")

    assert [
             nil,
             nil,
             "phoenix",
             "phx_reply",
             %{"status" => "error", "response" => %{"reason" => r1}}
           ] = WSClient.recv_frame(ws)

    assert r1 =~ "invalid JSON"

    WSClient.send_text(ws, ~s(["1","2","#{topic}","thrust","fast"]))

    assert [
             "1",
             "2",
             ^topic,
             "phx_reply",
             %{"response" => %{"reason" => "payload must be a JSON object"}}
           ] = WSClient.recv_frame(ws)

    WSClient.send_text(ws, ~s([1,2,3]))
    assert [_, _, "phoenix", "phx_reply", %{"status" => "error"}] = WSClient.recv_frame(ws)

    WSClient.send_binary(ws, <<1, 2, 3>>)

    assert [_, _, "phoenix", "phx_reply", %{"response" => %{"reason" => r2}}] =
             WSClient.recv_frame(ws)

    assert r2 =~ "binary frames are not supported"

    WSClient.push(ws, nil, "alive", "phoenix", "heartbeat", %{})
    assert [nil, "alive", "phoenix", "phx_reply", %{"status" => "ok"}] = WSClient.recv_frame(ws)
  end

  test "leave replies ok, closes the channel, and later pushes are unmatched", %{topic: topic} do
    ws = connect!()
    {join_ref, _} = join!(ws, topic)
    assert {"ok", %{}} = push_and_reply(ws, join_ref, topic, "phx_leave", %{})

    assert [^join_ref, ^join_ref, ^topic, "phx_close", %{}] =
             WSClient.recv_until(ws, &match?([_, _, _, "phx_close", _], &1))

    assert {"error", %{"reason" => "unmatched topic"}} =
             push_and_reply(ws, join_ref, topic, "thrust", thrust(0))
  end

  test "a rejoin replaces the old join; its join_ref goes stale", %{topic: topic} do
    ws = connect!()
    {old_ref, _} = join!(ws, topic)
    {new_ref, _} = join!(ws, topic)

    assert {"error", %{"reason" => "unmatched topic"}} =
             push_and_reply(ws, old_ref, topic, "thrust", thrust(0))

    # matched (the helm answers), unlike the stale join_ref
    assert {"error", %{"reason" => "not_in_control"}} =
             push_and_reply(ws, new_ref, topic, "thrust", thrust(0))
  end

  test "broadcasts are the same bytes for every subscriber (encoded once)", %{topic: topic} do
    [a, b] = for name <- ["a", "b"], do: connect!(name)
    for ws <- [a, b], do: join!(ws, topic)
    frame_a = raw_telemetry(a)
    t = :jiffy.decode(frame_a, [:return_maps]) |> Enum.at(4) |> Map.fetch!("t")
    frame_b = raw_telemetry_at(b, t)
    assert frame_a == frame_b
  end

  test "presence: joins and leaves reach the others", %{topic: topic} do
    a = connect!("Ada")
    join!(a, topic)
    b = connect!("Bob")
    join!(b, topic)

    assert [nil, nil, ^topic, "presence_diff", %{"joins" => %{"Bob" => _}, "leaves" => %{}}] =
             WSClient.recv_until(
               a,
               &match?([_, _, _, "presence_diff", %{"joins" => %{"Bob" => _}}], &1)
             )

    WSClient.close(b)

    assert [_, _, _, "presence_diff", %{"leaves" => %{"Bob" => %{"metas" => [_]}}}] =
             WSClient.recv_until(
               a,
               &match?([_, _, _, "presence_diff", %{"leaves" => %{"Bob" => _}}], &1)
             )
  end

  test "a failing channel sends phx_error for its topic only", %{id: id, topic: topic} do
    ws = connect!()
    {jr, _} = join!(ws, topic)
    join!(ws, "fleet")
    :ok = Neptunus.Fleet.stop_vehicle(id)
    # gone from the fleet's directory too (it hears of the stop a moment later): until then a
    # request finds the vehicle, is told "vehicle restarting: try again", and the channel lives
    Neptunus.Test.Pty.wait_until(
      fn -> not Neptunus.Fleet.exists?(id) end,
      "the stopped vehicle to be gone"
    )

    WSClient.push(ws, jr, "x", topic, "thrust", thrust(0))

    assert [^jr, ^jr, ^topic, "phx_error", %{}] =
             WSClient.recv_until(ws, &match?([_, _, _, "phx_error", _], &1))

    WSClient.push(ws, nil, "hb", "phoenix", "heartbeat", %{})
    assert [nil, "hb", _, "phx_reply", %{"status" => "ok"}] = reply_to(ws, "hb")
  end

  test "server connections have TCP_NODELAY (small replies are not held for delayed ACKs)" do
    _ws = connect!()
    server_port = port()

    accepted =
      for p <- Port.list(),
          Port.info(p, :name) == {:name, ~c"tcp_inet"},
          {:ok, {_, ^server_port}} <- [:inet.sockname(p)],
          {:ok, _peer} <- [:inet.peername(p)],
          do: p

    assert accepted != []
    for p <- accepted, do: assert({:ok, [nodelay: true]} = :inet.getopts(p, [:nodelay]))
  end

  test "priorities: connections :low, the pilot's :high and served first while in control",
       %{id: id, topic: topic} do
    ada = connect!("Ada")
    {ada_jr, _} = join!(ada, topic)
    [ada_pid] = connections(topic)
    bob = connect!("Bob")
    {_bob_jr, _} = join!(bob, topic)
    [bob_pid] = connections(topic) -- [ada_pid]

    assert priority(ada_pid) == :low and priority(bob_pid) == :low
    assert priority(Neptunus.Vehicle.Helm, id) == :high
    assert priority(Neptunus.Vehicle.Control, id) == :high
    assert first(topic) == []

    assert {"ok", %{"status" => "granted"}} =
             push_and_reply(ada, ada_jr, topic, "request_control", %{})

    # the connection acts on the grant before it pushes control_granted to its client
    WSClient.recv_until(ada, &match?([_, _, ^topic, "control_granted", _], &1))
    assert priority(ada_pid) == :high and priority(bob_pid) == :low
    assert first(topic) == [ada_pid]
    # telemetry still reaches both
    WSClient.recv_until(ada, &match?([_, _, ^topic, "telemetry", _], &1))
    WSClient.recv_until(bob, &match?([_, _, ^topic, "telemetry", _], &1))

    assert {"ok", _} = push_and_reply(ada, ada_jr, topic, "release_control", %{})
    WSClient.recv_until(ada, &match?([_, _, ^topic, "control_lost", _], &1))
    assert priority(ada_pid) == :low
    assert first(topic) == []

    # a pilot that leaves the topic is back at :low too
    assert {"ok", %{"status" => "granted"}} =
             push_and_reply(ada, ada_jr, topic, "request_control", %{})

    WSClient.recv_until(ada, &match?([_, _, ^topic, "control_granted", _], &1))
    assert priority(ada_pid) == :high
    assert {"ok", _} = push_and_reply(ada, ada_jr, topic, "phx_leave", %{})
    # control_lost is handled after the leave's reply: a heartbeat's reply comes after it
    WSClient.push(ada, nil, "hb", "phoenix", "heartbeat", %{})
    reply_to(ada, "hb")
    assert priority(ada_pid) == :low
    assert first(topic) == [] and connections(topic) == [bob_pid]
  end

  test "a pilot that sends more frames than its budget runs at :normal until the next second",
       %{topic: topic} do
    NeptunusWeb.Test.Wire.settings!(pilot_frames_per_s: 20)
    ada = connect!("Ada")
    {ada_jr, _} = join!(ada, topic)
    [ada_pid] = connections(topic)

    assert {"ok", %{"status" => "granted"}} =
             push_and_reply(ada, ada_jr, topic, "request_control", %{})

    WSClient.recv_until(ada, &match?([_, _, ^topic, "control_granted", _], &1))
    assert priority(ada_pid) == :high

    for i <- 1..30, do: WSClient.push(ada, nil, "f#{i}", "phoenix", "heartbeat", %{})
    reply_to(ada, "f30")
    assert priority(ada_pid) == :normal
    # still the pilot, still served: only its priority changed
    assert {"ok", _} = push_and_reply(ada, ada_jr, topic, "heartbeat", %{})

    # a frame in a later second finds a fresh budget
    Process.sleep(1_050)
    WSClient.push(ada, nil, "later", "phoenix", "heartbeat", %{})
    reply_to(ada, "later")
    assert priority(ada_pid) == :high
  end

  test "a broadcast frame for a topic the connection has left is not sent", %{topic: topic} do
    ws = connect!()
    {join_ref, _} = join!(ws, topic)
    [pid] = connections(topic)
    assert {"ok", _} = push_and_reply(ws, join_ref, topic, "phx_leave", %{})
    # e.g. the later slice of a paced broadcast, delivered after the leave
    send(
      pid,
      {:pubsub_frame, topic, "telemetry", ~s([null,null,"#{topic}","telemetry",{"late":true}])}
    )

    WSClient.push(ws, nil, "hb", "phoenix", "heartbeat", %{})
    refute Enum.any?(frames_until(ws, "hb"), &match?([_, _, _, _, %{"late" => true}], &1))
  end

  test "clock: anyone joined gets the server's wall clock, the clock of sent_at", %{
    topic: topic
  } do
    ws = connect!("Watcher")
    {join_ref, _} = join!(ws, topic)
    before = System.os_time(:microsecond) / 1000
    assert {"ok", %{"now" => now}} = push_and_reply(ws, join_ref, topic, "clock", %{})
    after_ = System.os_time(:microsecond) / 1000
    assert is_float(now) and before <= now and now <= after_

    # the same clock as telemetry's sent_at
    [_, _, ^topic, "telemetry", %{"sent_at" => sent_at}] =
      WSClient.recv_until(ws, &match?([_, _, ^topic, "telemetry", _], &1))

    assert abs(sent_at - System.os_time(:microsecond) / 1000) < 5_000
  end

  describe "slow clients" do
    test "a connection that falls behind drops stale telemetry, never other events",
         %{topic: topic} do
      ws = connect!("Slow")
      {_join_ref, _} = join!(ws, topic)
      [pid] = connections(topic)

      # the connection process is held up (as by a send into a full buffer) while the
      # broadcasts go on: 100 telemetry frames with a state change among them
      :sys.suspend(pid)

      for k <- 1..100 do
        Neptunus.PubSub.broadcast(topic, "telemetry", %{"k" => k})
        if k == 50, do: Neptunus.PubSub.broadcast(topic, "stopped", %{"reason" => "test"})
      end

      {:message_queue_len, waiting} = Process.info(pid, :message_queue_len)
      assert waiting >= 101

      log =
        ExUnit.CaptureLog.capture_log(fn ->
          :sys.resume(pid)
          WSClient.push(ws, nil, "hb", "phoenix", "heartbeat", %{})
          send(self(), {:frames, frames_until(ws, "hb")})
        end)

      assert_received {:frames, frames}
      ks = for [_, _, ^topic, "telemetry", %{"k" => k}] <- frames, do: k

      # the state change went out; of the telemetry only the newest, in order, the last one
      # included
      assert [_, _, ^topic, "stopped", %{"reason" => "test"}] =
               Enum.find(frames, &match?([_, _, _, "stopped", %{"reason" => "test"}], &1))

      backlog = NeptunusWeb.Endpoint.Settings.get().backlog
      assert length(ks) in 1..backlog
      assert List.last(ks) == 100
      assert ks == Enum.sort(ks) and hd(ks) > 100 - backlog
      assert log =~ ~s("Slow" reads slower than its telemetry arrives: dropped 1 stale)

      # caught up: telemetry flows again
      Neptunus.PubSub.broadcast(topic, "telemetry", %{"k" => 101})
      WSClient.recv_until(ws, &match?([_, _, ^topic, "telemetry", %{"k" => 101}], &1))
    end

    test "a pilot whose client stops reading is disconnected after the send timeout, " <>
           "and the vehicle stops",
         %{id: id, topic: topic} do
      ws = connect!("Frozen")
      {join_ref, _} = join!(ws, topic)
      [pid] = connections(topic)

      assert {"ok", %{"status" => "granted"}} =
               push_and_reply(ws, join_ref, topic, "request_control", %{})

      Neptunus.PubSub.subscribe(topic)
      ref = Process.monitor(pid)

      # the client stops reading (a frozen tab); the kernel's buffers on both ends fill up
      :sys.suspend(ws)
      pad = String.duplicate("x", 512 * 1024)
      started = System.monotonic_time(:millisecond)
      for _ <- 1..40, do: Neptunus.PubSub.broadcast(topic, "padding", %{"pad" => pad})

      timeout = NeptunusWeb.Endpoint.send_timeout_ms()
      assert_receive {:DOWN, ^ref, :process, ^pid, _}, timeout + 5_000
      assert System.monotonic_time(:millisecond) - started >= timeout

      # the pilot's helm is freed and the vehicle stopped (the deadman already had, as the
      # frozen client sent no heartbeats either)
      assert_receive {:pubsub, ^topic, "helm", %{pilot: nil}}
      assert %{pilot: nil} = Neptunus.Vehicle.Helm.status(id)

      assert %{thrusters: %{port: +0.0, vertical: +0.0, starboard: +0.0}} =
               Neptunus.Vehicle.Control.status(id)

      :sys.resume(ws)
    end

    test "the kernel holds at most `unsent_bytes` of a connection's frames unsent",
         %{topic: topic} do
      # the default, then another value for the connections opened after it is set
      assert NeptunusWeb.Endpoint.Settings.get().unsent_bytes == 4_096

      for bytes <- [4_096, 8_192] do
        NeptunusWeb.Test.Wire.settings!(unsent_bytes: bytes)
        ws = connect!("Lowat")
        {_join_ref, _} = join!(ws, topic)
        [pid] = connections(topic)

        # TCP_NOTSENT_LOWAT (IPPROTO_TCP 6, option 25), read back from the kernel
        assert {:ok, [{:raw, 6, 25, <<^bytes::native-32>>}]} =
                 :inet.getopts(server_socket(pid), [{:raw, 6, 25, 4}])

        ref = Process.monitor(pid)
        WSClient.close(ws)
        assert_receive {:DOWN, ^ref, :process, ^pid, _}
      end
    end

    test "a connection without telemetry finds its closed socket at the idle check" do
      ws = connect!("Quiet")
      {_join_ref, _} = join!(ws, "fleet")
      [pid] = connections("fleet") |> Enum.filter(&(server_socket(&1) != nil))
      sock = server_socket(pid)
      ref = Process.monitor(pid)

      :sys.suspend(ws)
      pad = String.duplicate("x", 512 * 1024)
      for _ <- 1..40, do: Neptunus.PubSub.broadcast("fleet", "padding", %{"pad" => pad})

      # the send timeout closes the socket under the connection, which does not notice ...
      Neptunus.Test.Pty.wait_until(
        fn -> :inet.peername(sock) == {:error, :enotconn} end,
        "the send timeout to close the socket"
      )

      refute_receive {:DOWN, ^ref, :process, ^pid, _}, 200
      # ... until its next idle check (every quarter of the idle timeout)
      send(pid, :check_idle)
      assert_receive {:DOWN, ^ref, :process, ^pid, _}
      :sys.resume(ws)
    end
  end

  defp server_socket(pid) do
    {:links, links} = Process.info(pid, :links)
    Enum.find(links, &is_port/1)
  end

  defp frames_until(ws, ref, acc \\ []) do
    case WSClient.recv_frame(ws) do
      [_, ^ref, _, "phx_reply", _] -> Enum.reverse(acc)
      frame -> frames_until(ws, ref, [frame | acc])
    end
  end

  # the server-side connection processes subscribed to `topic` (served first or not)
  defp connections(topic),
    do: :pg.get_local_members(Neptunus.PubSub, {:fastlane, topic}) ++ first(topic)

  defp first(topic), do: :pg.get_local_members(Neptunus.PubSub, {:fastlane_first, topic})

  defp priority(pid) do
    {:priority, priority} = Process.info(pid, :priority)
    priority
  end

  defp priority(module, id),
    do: module |> Neptunus.Fleet.via(id) |> GenServer.whereis() |> priority()

  test "GET /api/health" do
    {:ok, {{_, 200, _}, headers, body}} =
      :httpc.request(~c"http://127.0.0.1:#{port()}/api/health")

    assert {~c"content-type", ~c"application/json"} in headers

    assert %{"status" => "ok", "version" => _, "vehicles" => [_ | _]} =
             :jiffy.decode(body, [:return_maps])

    {:ok, {{_, 404, _}, _, body}} = :httpc.request(~c"http://127.0.0.1:#{port()}/api/nope")
    assert :jiffy.decode(body, [:return_maps]) == %{"error" => "no such API endpoint: /api/nope"}
  end

  defp raw_telemetry(ws) do
    receive do
      {:ws, ^ws, {:text, text}} ->
        if text =~ ~s("telemetry"), do: text, else: raw_telemetry(ws)
    after
      1000 -> flunk("no telemetry")
    end
  end

  defp raw_telemetry_at(ws, t) do
    text = raw_telemetry(ws)

    if :jiffy.decode(text, [:return_maps]) |> Enum.at(4) |> Map.fetch!("t") == t,
      do: text,
      else: raw_telemetry_at(ws, t)
  end
end
