defmodule NeptunusWeb.FleetClusterTest do
  @moduledoc """
  A fleet of two nodes on one machine: the test node (T, the topside, serving on the test
  port) and a peer (V, serving on the next ports, hosting the vehicle), through real
  WebSockets on both (see `Neptunus.Test.Cluster`).
  """
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias Neptunus.Fleet
  alias Neptunus.Test.Cluster
  alias NeptunusWeb.Test.WSClient

  @moduletag timeout: 120_000

  setup_all do
    Cluster.distribute!()
    :ok
  end

  # each test its own vehicle node, on its own port (the test port + 1..8)
  defp start_vehicle_node!(ctx, offset) do
    id = "far-#{System.unique_integer([:positive])}"
    name = :"fleet_v#{port()}_#{System.unique_integer([:positive])}"
    peer = Cluster.start_node!(name, port() + offset, [%{id: id, board: :simulated}])
    on_exit(fn -> Cluster.stop_node(peer) end)
    Map.merge(ctx, %{peer: peer, id: id, topic: "vehicle:" <> id})
  end

  defp connect_to!(port, name) do
    query = URI.encode_query(%{"vsn" => "2.0.0", "name" => name})
    {:ok, ws} = WSClient.connect(port, "/socket/websocket?" <> query)
    ws
  end

  defp health(port) do
    {:ok, {{_, 200, _}, _, body}} =
      :httpc.request(:get, {~c"http://127.0.0.1:#{port}/api/health", []}, [], [])

    :jiffy.decode(body, [:return_maps])
  end

  test "one directory: each node lists the other's vehicles with their node", ctx do
    %{peer: peer, id: id} = start_vehicle_node!(ctx, 1)
    v = Atom.to_string(peer.node)
    t = Atom.to_string(node())

    assert %{"status" => "up", "node" => ^v, "board" => "simulated", "helm" => "free"} =
             Enum.find(health(port())["vehicles"], &(&1["id"] == id))

    # a fleet overview: the vehicle's depth, heading, link and recording (once it has telemetry)
    Cluster.wait!(
      fn -> is_number(Enum.find(Fleet.directory(), &(&1.id == id)).depth) end,
      "depth of #{id}"
    )

    assert %{heading: heading, link: %{up: true}, recording: false, pilot: nil} =
             Enum.find(Fleet.directory(), &(&1.id == id))

    assert is_number(heading)

    # the vehicle node sees the topside's vehicle too
    assert %{"node" => ^t, "status" => "up"} =
             Enum.find(health(peer.port)["vehicles"], &(&1["id"] == "neptunus-1"))

    # and T lists its own vehicle on its node as named now (it joined the directory before
    # the test node became distributed)
    assert %{"node" => ^t, "status" => "up"} =
             Enum.find(health(port())["vehicles"], &(&1["id"] == "neptunus-1"))

    ws = connect!()
    {_, %{"vehicles" => vehicles}} = join!(ws, "fleet")
    assert %{"node" => ^v} = Enum.find(vehicles, &(&1["id"] == id))
  end

  test "a browser on T flies the vehicle on V: join, telemetry, control, commands, presence",
       ctx do
    %{peer: peer, id: id, topic: topic} = start_vehicle_node!(ctx, 2)
    v = Atom.to_string(peer.node)

    ws = connect!(%{"name" => "Ada"})
    {jr, snapshot} = join!(ws, topic)
    assert %{"vehicle" => %{"id" => ^id, "node" => ^v}, "helm" => %{"state" => "free"}} = snapshot

    # telemetry crosses (the vehicle's node broadcasts it, T's relay serves it)
    assert %{"t" => _} = event!(ws, "telemetry")
    # the developer logger's topic of a vehicle on V is joined on T too
    assert {_, %{"vehicle" => ^id}} = join!(connect!(), "log:" <> id)

    {"ok", %{"status" => "granted", "grant" => %{"epoch" => epoch}}} =
      push_and_reply(ws, jr, topic, "request_control", %{})

    assert {"ok", _} = push_and_reply(ws, jr, topic, "heartbeat", %{})
    assert {"ok", _} = push_and_reply(ws, jr, topic, "thrust", thrust(0.5, epoch))

    # the helm and the command are on V
    assert %{pilot: %{name: "Ada"}, state: "piloted"} =
             Cluster.call(peer, Neptunus.Vehicle.Helm, :status, [id])

    assert %{"command" => %{"surge" => surge}} =
             event!(ws, "telemetry", &(get_in(&1, ["command", "surge"]) not in [nil, 0, 0.0]))

    assert surge > 0

    # the vehicle's tuning and settings live on V: read and set from T by the pilot
    assert {"ok", %{"gains" => %{"depth" => %{"kp" => _}}}} =
             push_and_reply(ws, jr, topic, "get_tuning", %{})

    assert {"ok", %{"camera_rotation" => 90}} =
             push_and_reply(ws, jr, topic, "set_camera_rotation", %{"value" => 90})

    assert %{camera_rotation: 90} = Cluster.call(peer, Neptunus.Vehicle.ViewSettings, :get, [id])

    # an observer on V sees the pilot from T, and presence counts both nodes' connections
    observer = connect_to!(peer.port, "Grace")
    {:ok, %{"pilot" => %{"name" => "Ada"}}} = WSClient.join(observer, topic)

    [_, _, _, "presence_state", state] =
      WSClient.recv_until(observer, &match?([_, _, _, "presence_state", _], &1))

    assert %{"Ada" => %{"metas" => [%{"node" => ada_node, "pilot" => true}]}, "Grace" => _} =
             state

    assert ada_node == Atom.to_string(node())

    # the presence diff of V's join reaches T
    assert %{"joins" => %{"Grace" => _}} =
             event!(ws, "presence_diff", &Map.has_key?(&1["joins"], "Grace"))
  end

  test "telemetry crosses once per node: one relay on T however many sockets", ctx do
    %{peer: peer, id: id, topic: topic} = start_vehicle_node!(ctx, 3)

    clients =
      for n <- 1..3 do
        ws = connect!(%{"name" => "watcher#{n}"})
        join!(ws, topic)
        ws
      end

    relay = Process.whereis(Neptunus.PubSub.Relay)

    Cluster.wait!(
      fn ->
        Cluster.call(peer, :pg, :get_members, [Neptunus.PubSub, {:relay, topic}]) == [relay]
      end,
      "T's relay in V's relay group"
    )

    # what the vehicle's telemetry process sends across: only to T's relay, whatever the
    # number of sockets on T
    telemetry = Cluster.call(peer, Fleet, :whereis, [Neptunus.Vehicle.Telemetry, id])
    {:ok, tracer} = Cluster.call(peer, Cluster.SendTracer, :start, [telemetry])

    for ws <- clients, do: assert(%{"t" => _} = event!(ws, "telemetry"))

    receivers = fn -> Cluster.call(peer, Cluster.SendTracer, :remote_receivers, [tracer]) end
    Cluster.wait!(fn -> Map.get(receivers.(), relay, 0) >= 3 end, "three broadcasts to T's relay")
    assert Map.keys(receivers.()) == [relay]
  end

  test "partition: the pilot on T loses control on V, T says unreachable; healing needs a fresh request",
       ctx do
    %{peer: peer, id: id, topic: topic} = start_vehicle_node!(ctx, 4)
    {:ok, collector} = Cluster.call(peer, Cluster.Collector, :start, [topic])

    ws = connect!(%{"name" => "Ada"})
    {jr, _} = join!(ws, topic)

    {"ok", %{"status" => "granted", "grant" => %{"epoch" => epoch}}} =
      push_and_reply(ws, jr, topic, "request_control", %{})

    assert {"ok", _} = push_and_reply(ws, jr, topic, "thrust", thrust(0.6, epoch))

    Cluster.partition!(peer)

    # T: at once, the vehicle is unreachable (no frozen telemetry passed off as live), and
    # the pilot here has lost control
    assert %{"id" => ^id, "reason" => "node_unreachable"} = event!(ws, "unreachable")
    assert %{"reason" => "pilot_unreachable"} = event!(ws, "control_lost")
    assert {:error, :unreachable} = Fleet.locate(id)

    assert %{"status" => "unreachable", "helm" => nil} =
             Enum.find(Fleet.directory(), &(&1.id == id)) |> stringify()

    assert {"error", %{"reason" => "vehicle_unreachable"}} =
             push_and_reply(ws, jr, topic, "thrust", thrust(0.6, epoch))

    # V: the pilot's connection is gone: neutral, and why (the event, not its timing)
    Cluster.wait!(
      fn ->
        {"stopped", %{reason: "pilot_unreachable"}} in Cluster.call(
          peer,
          Cluster.Collector,
          :events,
          [collector]
        )
      end,
      "V stops the vehicle: pilot_unreachable"
    )

    assert %{pilot: nil, state: "free"} = Cluster.call(peer, Neptunus.Vehicle.Helm, :status, [id])

    assert %{command: command} = Cluster.call(peer, Neptunus.Vehicle.Telemetry, :latest, [id])

    assert Enum.all?(Map.take(command, [:surge, :sway, :heave, :yaw]), fn {_, v} ->
             v in [0, 0.0, nil]
           end)

    Cluster.heal!(peer)
    assert %{"id" => ^id} = event!(ws, "reachable")
    # the helm's state now (its broadcasts while apart never reached T): free
    assert %{"state" => "free", "pilot" => nil} = event!(ws, "helm")
    assert %{"t" => _} = event!(ws, "telemetry")

    # nobody in control after healing: the old grant is void, a fresh request picks up
    assert {"error", %{"reason" => "not_in_control"}} =
             push_and_reply(ws, jr, topic, "thrust", thrust(0.6, epoch))

    assert {"ok", %{"status" => "granted"}} =
             push_and_reply(ws, jr, topic, "request_control", %{})
  end

  test "a vehicle node that restarts: unreachable, then up again with telemetry", ctx do
    %{peer: peer, id: id, topic: topic} = start_vehicle_node!(ctx, 5)
    ws = connect!(%{"name" => "Ada"})
    join!(ws, topic)
    assert %{"t" => _} = event!(ws, "telemetry")

    # a clean shutdown: its vehicles stop, then the node goes
    Cluster.call(peer, :init, :stop, [])
    assert %{"id" => ^id} = event!(ws, "unreachable", fn _ -> true end)
    Cluster.wait!(fn -> peer.node not in Node.list() end, "V down")
    # the directory announces what it already shows
    assert %{status: "unreachable"} = Enum.find(Fleet.directory(), &(&1.id == id))

    [name, _] = peer.node |> Atom.to_string() |> String.split("@")
    again = Cluster.start_node!(String.to_atom(name), peer.port, [%{id: id, board: :simulated}])
    on_exit(fn -> Cluster.stop_node(again) end)

    assert %{"id" => ^id} = event!(ws, "reachable", fn _ -> true end)
    assert %{"t" => _} = event!(ws, "telemetry")
    assert %{status: "up", helm: "free"} = Enum.find(Fleet.directory(), &(&1.id == id))
  end

  defp stringify(map), do: Map.new(map, fn {k, v} -> {Atom.to_string(k), v} end)

  @tag :tmp_dir
  test "recordings and camera of a vehicle on V: listed, exported and watched from T", ctx do
    script = Path.expand("../fixtures/camera/fake_camera.sh", __DIR__)
    id = "far-cam-#{System.unique_integer([:positive])}"
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [script, "0"]}
    recording = Map.put(Application.get_env(:neptunus, :recording), :dir, ctx.tmp_dir)
    name = :"fleet_v#{port()}_#{System.unique_integer([:positive])}"

    peer =
      Cluster.start_node!(name, port() + 6, [%{id: id, board: :simulated, camera: camera}],
        recording: recording
      )

    on_exit(fn -> Cluster.stop_node(peer) end)
    v = Atom.to_string(peer.node)

    list = fn query ->
      {:ok, {{_, 200, _}, _, body}} =
        :httpc.request(:get, {~c"http://127.0.0.1:#{port()}/api/recordings#{query}", []}, [], [])

      :jiffy.decode(body, [:return_maps])
    end

    Cluster.wait!(fn -> list.("?vehicle=#{id}")["recordings"] != [] end, "a recording on V")

    assert %{"recording" => true, "recordings" => [%{"node" => ^v, "name" => file}]} =
             list.("?vehicle=#{id}")

    assert Enum.any?(list.("")["recordings"], &(&1["vehicle"] == id and &1["node"] == v))

    {:ok, {{_, 200, _}, _, csv}} =
      :httpc.request(
        :get,
        {~c"http://127.0.0.1:#{port()}/api/recordings/#{id}/#{file}?format=csv", []},
        [],
        body_format: :binary
      )

    assert [header | rows] = String.split(csv, "\n", trim: true)
    assert header =~ "t"
    assert rows != []

    # the camera: the snapshot's url on T streams V's camera
    ws = connect!()
    {_, %{"camera" => %{"url" => url}}} = join!(ws, "vehicle:" <> id)
    {200, headers, body, socket} = raw_get(url)
    assert headers["content-type"] == "multipart/x-mixed-replace; boundary=neptunusframe"
    assert read_until(socket, body, "Content-Type: image/jpeg")
    :gen_tcp.close(socket)
  end

  test "camera frames cross to T once per frame, not once per viewer on T" do
    script = Path.expand("../fixtures/camera/fake_camera.sh", __DIR__)
    id = "far-cam-#{System.unique_integer([:positive])}"
    camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [script, "0"]}
    name = :"fleet_v#{port()}_#{System.unique_integer([:positive])}"
    peer = Cluster.start_node!(name, port() + 5, [%{id: id, board: :simulated, camera: camera}])
    on_exit(fn -> Cluster.stop_node(peer) end)

    # what the camera process on V sends to other nodes
    broadcaster = Cluster.call(peer, Fleet, :whereis, [Neptunus.Vehicle.Camera, id])
    assert is_pid(broadcaster)
    {:ok, tracer} = Cluster.call(peer, Cluster.SendTracer, :start, [broadcaster])

    # three viewers on T
    viewers =
      for _ <- 1..3 do
        {200, headers, body, socket} = raw_get("/camera/#{id}.mjpg")
        assert headers["content-type"] =~ "multipart/x-mixed-replace"
        {socket, body}
      end

    # each gets new frames (at least three parts each)
    for {socket, body} <- viewers,
        do: assert(read_parts(socket, body, 3))

    # one receiver on T (this node's relay), not one per viewer
    receivers = Cluster.call(peer, Cluster.SendTracer, :remote_receivers, [tracer])
    assert map_size(receivers) == 1, "receivers on T: #{inspect(receivers)}"
    assert Map.keys(receivers) == [NeptunusWeb.CameraRelay.whereis(id)]

    # the last viewer gone, the relay stops
    for {socket, _} <- viewers, do: :gen_tcp.close(socket)
    Cluster.wait!(fn -> NeptunusWeb.CameraRelay.whereis(id) == nil end, "the relay stops")
  end

  test "video frames cross to T once per frame, not once per viewer on T" do
    id = "far-video-#{System.unique_integer([:positive])}"
    {:ok, camera} = Neptunus.Camera.Source.parse("testsrc@h264@320x240@15")
    name = :"fleet_v#{port()}_#{System.unique_integer([:positive])}"
    peer = Cluster.start_node!(name, port() + 9, [%{id: id, board: :simulated, camera: camera}])
    on_exit(fn -> Cluster.stop_node(peer) end)

    broadcaster = Cluster.call(peer, Fleet, :whereis, [Neptunus.Vehicle.Camera, id])
    {:ok, tracer} = Cluster.call(peer, Cluster.SendTracer, :start, [broadcaster])

    # three video viewers on T: each gets the stream and frames from a keyframe
    viewers =
      for _ <- 1..3 do
        {:ok, ws} = NeptunusWeb.Test.Video.connect(id)
        ws
      end

    for ws <- viewers do
      {[first | _], texts} = NeptunusWeb.Test.Video.frames(ws, 5)
      assert first.keyframe
      assert Enum.any?(texts, &(&1["event"] == "stream" and &1["codec"] == "h264"))
    end

    receivers = Cluster.call(peer, Cluster.SendTracer, :remote_receivers, [tracer])
    assert Map.keys(receivers) == [NeptunusWeb.CameraRelay.whereis(id)]

    for ws <- viewers, do: NeptunusWeb.Test.WSClient.close(ws)
    Cluster.wait!(fn -> NeptunusWeb.CameraRelay.whereis(id) == nil end, "the relay stops")
  end

  defp read_parts(socket, acc, n) do
    parts = length(String.split(acc, "Content-Type: image/jpeg")) - 1

    if parts >= n do
      true
    else
      {:ok, more} = :gen_tcp.recv(socket, 0, Neptunus.Test.Patience.ms())
      read_parts(socket, acc <> more, n)
    end
  end

  defp read_until(socket, acc, text) do
    if String.contains?(acc, text) do
      true
    else
      {:ok, more} = :gen_tcp.recv(socket, 0, Neptunus.Test.Patience.ms())
      read_until(socket, acc <> more, text)
    end
  end

  @tag :external
  test "the official phoenix JS client on T drives the vehicle on V (the protocol suite)", ctx do
    %{id: id} = start_vehicle_node!(ctx, 7)
    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")
    root = Path.expand("../..", __DIR__)

    {output, status} =
      System.cmd(
        node,
        ["--test", "--test-reporter=spec", "assets/test/protocol/vehicle.test.mjs"],
        cd: root,
        env: [{"NEPTUNUS_URL", "http://127.0.0.1:#{port()}"}, {"NEPTUNUS_VEHICLE", id}],
        stderr_to_stdout: true
      )

    assert status == 0, "the protocol suite failed against #{id} on V:\n#{output}"
    assert output =~ ~r/pass \d+/
    refute output =~ ~r/fail [1-9]/
  end

  @tag :external
  test "a browser on T picks the vehicle on V and takes control (Chromium)", ctx do
    %{peer: peer, id: id} = start_vehicle_node!(ctx, 8)
    root = Path.expand("../..", __DIR__)
    # the browser's pilot is on T, the helm it took on V (the page's helm state says "pilot")

    unless File.exists?(Path.join(root, "priv/static/index.html")),
      do: flunk("priv/static is not built: run `make assets`")

    node = System.find_executable("node") || flunk("node is not installed: run `make setup`")

    {output, status} =
      System.cmd(node, ["--test", "--test-reporter=spec", "test/e2e/fleet.e2e.mjs"],
        cd: root,
        env: [
          {"NEPTUNUS_URL", "http://127.0.0.1:#{port()}"},
          {"FLEET_VEHICLE", id},
          {"FLEET_NODE", Atom.to_string(peer.node)}
        ],
        stderr_to_stdout: true
      )

    assert status == 0, "the browser test failed:\n#{output}"
    refute output =~ ~r/fail [1-9]/
  end

  test "a node taken out of the fleet: its vehicles are forgotten, not listed unreachable", ctx do
    %{peer: peer, id: id} = start_vehicle_node!(ctx, 1)
    Cluster.partition!(peer)
    Cluster.wait!(fn -> Fleet.locate(id) == {:error, :unreachable} end, "#{id} unreachable")
    :ok = Neptunus.Fleet.Directory.forget(peer.node)
    assert Fleet.locate(id) == {:error, :not_found}
    refute Enum.any?(Fleet.directory(), &(&1.id == id))
  end

  test "the connector reconnects to a node of NEPTUNUS_CLUSTER after a cut, with backoff", ctx do
    %{peer: peer, id: id} = start_vehicle_node!(ctx, 2)
    connector = start_supervised!({Neptunus.Fleet.Connector, [peer.node]})
    Cluster.partition!(peer)
    Cluster.wait!(fn -> Fleet.locate(id) == {:error, :unreachable} end, "#{id} unreachable")
    # the peer accepts us again; nobody but the connector connects
    :ok = Cluster.call(peer, :net_kernel, :allow, [[node()]])
    Cluster.wait!(fn -> peer.node in Node.list() end, "the connector reconnects")
    Cluster.await_located!(id, peer.node)
    assert Process.alive?(connector)
  end
end
