defmodule NeptunusWeb.RestartTest do
  # The PubSub scope and the presence server restart under live clients and a recording
  # vehicle: nobody is left subscribed to nothing without being told. These tests kill
  # application-wide processes, so they run alone (async: false).
  use ExUnit.Case, async: false

  alias Neptunus.{PubSub, Recording}
  alias Neptunus.PubSub.Follow
  alias Neptunus.Vehicle.{Camera, Recorder, Telemetry}
  alias NeptunusWeb.Presence
  alias NeptunusWeb.Test.{Wire, WSClient}

  @moduletag :capture_log

  # The application's supervisor allows 3 restarts in 5 s: kills of this module stay apart.
  @kill_gap_ms 2_000

  defp kill!(name) do
    case :persistent_term.get({__MODULE__, :last_kill}, nil) do
      nil -> :ok
      at -> Process.sleep(max(at + @kill_gap_ms - System.monotonic_time(:millisecond), 0))
    end

    pid = Process.whereis(name) || flunk("#{inspect(name)} is not running")
    ref = Process.monitor(pid)
    Process.exit(pid, :kill)
    assert_receive {:DOWN, ^ref, :process, ^pid, :killed}
    :persistent_term.put({__MODULE__, :last_kill}, System.monotonic_time(:millisecond))
    pid
  end

  # Holds the application's supervisor (no restart) while `fun` runs; then the dead child
  # is restarted.
  defp with_restart_held(fun) do
    :ok = :sys.suspend(Neptunus.Supervisor)

    try do
      fun.()
    after
      :ok = :sys.resume(Neptunus.Supervisor)
    end
  end

  defp eventually(fun, timeout \\ Neptunus.Test.Patience.ms()) do
    deadline = System.monotonic_time(:millisecond) + timeout
    do_eventually(fun, deadline)
  end

  defp do_eventually(fun, deadline) do
    case fun.() do
      falsy when falsy in [nil, false] ->
        if System.monotonic_time(:millisecond) > deadline, do: flunk("condition never held")
        Process.sleep(20)
        do_eventually(fun, deadline)

      value ->
        value
    end
  end

  defp closed!(ws) do
    assert_receive {:ws, ^ws, {:close, code, reason}}
    {code, reason}
  end

  # Joins again as the phoenix client does after a close: retries while the server says it
  # is restarting.
  defp rejoin!(topic, name) do
    eventually(fn ->
      ws = Wire.connect!(%{name: name})

      case WSClient.join(ws, topic) do
        {:ok, _snapshot} ->
          ws

        {:error, %{"reason" => "server restarting: join again"}} ->
          WSClient.close(ws)
          nil
      end
    end)
  end

  describe "PubSub restart" do
    setup do
      Wire.start_vehicle!("resub")
    end

    test "every joined client's connection is closed (1012) and, rejoined, gets telemetry",
         %{topic: topic} do
      pilot = Wire.client!(topic, %{name: "pilot"})
      observer = Wire.client!(topic, %{name: "observer"})
      assert {"ok", _} = Wire.push_and_reply(pilot.ws, pilot.jr, topic, "request_control", %{})
      Wire.event!(pilot.ws, "control_granted")
      Wire.event!(observer.ws, "telemetry")

      kill!(Neptunus.PubSub)

      # told: both connections end, so the clients reconnect and rejoin
      assert {1012, "service restart"} = closed!(pilot.ws)
      assert {1012, "service restart"} = closed!(observer.ws)

      ws = rejoin!(topic, "observer")
      assert %{"t" => _} = Wire.event!(ws, "telemetry")
      # the pilot's channel was left with its connection: the helm is free again
      assert %{pilot: nil} = Neptunus.Vehicle.Helm.status(String.trim_leading(topic, "vehicle:"))
    end

    test "a join while the scope is down is refused with a reason, and works once it is back",
         %{topic: topic} do
      ws = Wire.connect!(%{name: "early"})

      with_restart_held(fn ->
        kill!(Neptunus.PubSub)

        assert {:error, %{"reason" => "server restarting: join again"}} = WSClient.join(ws, topic)
      end)

      ws = rejoin!(topic, "early")
      assert %{"t" => _} = Wire.event!(ws, "telemetry")
    end
  end

  describe "PubSub restart under a follower" do
    # A long-lived process holding a Follow: it reports what the follow says, and the
    # broadcasts it gets.
    defp follower(topics) do
      test = self()

      spawn_link(fn ->
        {event, follow} = Follow.subscribe(Follow.new(topics))
        send(test, {:follow, self(), event})
        follow_loop(test, follow)
      end)
    end

    defp follow_loop(test, follow) do
      receive do
        {:pubsub, _topic, _event, _payload} = broadcast ->
          send(test, {:got, self(), broadcast})
          follow_loop(test, follow)

        message ->
          {event, follow} = Follow.handle(follow, message)
          send(test, {:follow, self(), event})
          follow_loop(test, follow)
      end
    end

    test "it is told its subscriptions are gone, waits for the scope, and subscribes again" do
      t = "resub-follow-#{System.unique_integer([:positive])}"
      pid = follower([t])
      assert_receive {:follow, ^pid, :subscribed}

      with_restart_held(fn ->
        kill!(Neptunus.PubSub)
        assert_receive {:follow, ^pid, :lost}
        # the scope is held down: the retry finds nothing, and tries again
        assert_receive {:follow, ^pid, :waiting}
        assert_receive {:follow, ^pid, :waiting}
      end)

      assert_receive {:follow, ^pid, :subscribed}
      assert PubSub.subscriber_count(t) == 1
      PubSub.broadcast(t, "ev", %{n: 1})
      assert_receive {:got, ^pid, {:pubsub, ^t, "ev", %{n: 1}}}

      # killed and restarted at once: the retry may find the new scope at the first try
      kill!(Neptunus.PubSub)
      assert_receive {:follow, ^pid, :lost}
      assert_receive {:follow, ^pid, :subscribed}
      assert PubSub.subscriber_count(t) == 1
      PubSub.broadcast(t, "ev", %{n: 2})
      assert_receive {:got, ^pid, {:pubsub, ^t, "ev", %{n: 2}}}
    end
  end

  describe "PubSub restart under a camera viewer" do
    setup do
      id = "resub-cam-#{System.unique_integer([:positive])}"
      script = Path.expand("../fixtures/camera/fake_camera.sh", __DIR__)
      camera = %{kind: :exec, codec: :mjpeg, program: "/bin/sh", args: [script, "0"]}
      {:ok, _} = Neptunus.Fleet.start_vehicle(%{id: id, board: :simulated, camera: camera})
      on_exit(fn -> Neptunus.Fleet.stop_vehicle(id) end)
      {:ok, id: id}
    end

    test "the viewer's stream subscribes again", %{id: id} do
      {200, _headers, _body, socket} = Wire.raw_get("/camera/#{id}.mjpg")
      topic = Camera.topic(id)
      eventually(fn -> PubSub.subscriber_count(topic) == 1 end)

      kill!(Neptunus.PubSub)

      eventually(fn -> PubSub.subscriber_count(topic) == 1 end)
      :gen_tcp.close(socket)
    end
  end

  describe "PubSub restart under a rendering simulated camera" do
    test "the camera follows the simulator's pose again" do
      id = "resub-sim-#{System.unique_integer([:positive])}"
      {:ok, source} = Neptunus.Camera.Source.parse("sim@384x216@10")
      start_supervised!({Camera, id: id, camera: source})
      # watched: it renders, and follows the pose
      :ok = PubSub.subscribe(Camera.topic(id))
      _ = Camera.view(id)
      pose = Neptunus.Camera.Pose.topic(id)
      eventually(fn -> PubSub.subscriber_count(pose) == 1 end)

      kill!(Neptunus.PubSub)

      # still watched (its viewer subscribes again too)
      eventually(fn -> PubSub.subscribe(Camera.topic(id)) == :ok end)
      eventually(fn -> PubSub.subscriber_count(pose) == 1 end)
    end
  end

  describe "PubSub restart while recording" do
    @describetag :tmp_dir

    test "the recorder says it is not recording, why, and records again", %{tmp_dir: dir} do
      id = "resub-rec-#{System.unique_integer([:positive])}"
      start_supervised!({Recorder, id: id, recording: [dir: dir]})
      topic = Telemetry.topic(id)
      # subscribed (handle_continue has run) once a call is answered
      assert %{recording: true, error: nil} = Recorder.status(id)
      PubSub.broadcast(topic, "telemetry", %{t: 1.0})

      with_restart_held(fn ->
        kill!(Neptunus.PubSub)

        status = eventually(fn -> with %{recording: false} = s <- Recorder.status(id), do: s end)
        assert status.error =~ "PubSub"
        # nothing reaches it meanwhile, and it does not pretend otherwise
        PubSub.broadcast(topic, "telemetry", %{t: 2.0})
      end)

      eventually(fn -> match?(%{recording: true, error: nil}, Recorder.status(id)) end)
      eventually(fn -> PubSub.subscriber_count(topic) == 1 end)
      PubSub.broadcast(topic, "telemetry", %{t: 3.0})
      PubSub.broadcast(topic, "stopped", %{reason: "deadman"})
      Recorder.sync(id)

      recorded = Recorder.status(id).files |> Enum.flat_map(&Enum.to_list(Recording.entries(&1)))

      # the gap is in the recording too (the recorder records the vehicle's log entries)
      assert [
               {_, "telemetry", %{t: 1.0}},
               {_, "log", %{category: "errors", message: "the PubSub restarted: " <> _}},
               {_, "telemetry", %{t: 3.0}},
               {_, "stopped", _}
             ] = recorded
    end
  end

  describe "PubSub restart while recording video" do
    @describetag :tmp_dir

    test "the video writer subscribes again: the camera's frames after it are written",
         %{tmp_dir: dir} do
      id = "resub-video-#{System.unique_integer([:positive])}"
      start_supervised!({Recorder, id: id, recording: [dir: dir]})
      topic = Camera.record_topic(id)
      # the dive is open and its writer told where to write once a call is answered
      assert %{recording: true} = Recorder.status(id)
      eventually(fn -> PubSub.subscriber_count(topic) == 1 end)
      video_frame(topic, 0, true)
      eventually(fn -> match?(%{video: %{frames: 1}}, Recorder.status(id)) end)

      kill!(Neptunus.PubSub)

      eventually(fn -> PubSub.subscriber_count(topic) == 1 end)
      video_frame(topic, 1, false)
      eventually(fn -> match?(%{video: %{frames: 2}}, Recorder.status(id)) end)
    end
  end

  defp video_frame(topic, seq, key) do
    frame =
      Neptunus.Camera.Frame.new(:h264, "picture #{seq}",
        keyframe: key,
        generation: 1,
        seq: seq,
        arrival_us: Neptunus.Clock.wall_us(),
        capture_us: 7
      )

    PubSub.broadcast(topic, "frame", %{frame: frame})
  end

  describe "Presence restart" do
    setup do
      Wire.start_vehicle!("resub-presence")
    end

    test "every joined client's presence state is right again", %{topic: topic} do
      clients =
        for name <- ~w(ada bob cyd), into: %{}, do: {name, Wire.client!(topic, %{name: name})}

      states =
        Map.new(clients, fn {name, c} -> {name, sync_until(c.ws, %{}, &(map_size(&1) == 3))} end)

      assert Enum.all?(states, fn {_, state} -> Map.keys(state) == ~w(ada bob cyd) end)

      with_restart_held(fn ->
        kill!(Presence)
        # cyd leaves while nobody keeps the presences: no one could tell the others
        WSClient.close(clients["cyd"].ws)
        assert_receive {:ws, _, :closed}
      end)

      for name <- ~w(ada bob) do
        ws = clients[name].ws
        # the state this client converges to is the server's, with the new metas
        # (both connections track again, each in its own time: wait for the state with both)
        state =
          sync_until(ws, states[name], fn state ->
            Map.keys(state) == ~w(ada bob) and
              refs(state) == refs(Presence.list(topic) |> stringify())
          end)

        assert Map.keys(state) == ~w(ada bob)
        refute refs(state) == refs(Map.take(states[name], ~w(ada bob)))
      end
    end
  end

  describe "Presence restart, then a join" do
    setup do
      Wire.start_vehicle!("resub-presence-join")
    end

    test "a join that finds the new server first still has the other channels track again",
         %{topic: topic} do
      ada = Wire.client!(topic, %{name: "ada"})
      sync_until(ada.ws, %{}, &(map_size(&1) == 1))

      with_restart_held(fn -> kill!(Presence) end)
      # right after the restart, before or after the connection's own retry finds the server
      Wire.join!(ada.ws, "fleet")

      state =
        sync_until(ada.ws, %{}, fn state ->
          refs(state) == refs(Presence.list(topic) |> stringify())
        end)

      assert Map.keys(state) == ["ada"]
    end
  end

  # The phoenix JS client's presence sync: presence_state replaces the state, a diff's joins
  # add metas (once per phx_ref) and its leaves remove them.
  defp sync_until(ws, state, done?) do
    if done?.(state) and state != %{} do
      state
    else
      [_, _, _, event, payload] =
        WSClient.recv_until(
          ws,
          &match?([_, _, _, e, _] when e in ~w(presence_state presence_diff), &1)
        )

      state =
        case event do
          "presence_state" -> payload
          "presence_diff" -> state |> join(payload["joins"]) |> leave(payload["leaves"])
        end

      sync_until(ws, state, done?)
    end
  end

  defp join(state, joins) do
    Enum.reduce(joins, state, fn {key, %{"metas" => metas}}, state ->
      Map.update(state, key, %{"metas" => metas}, fn %{"metas" => current} ->
        new = MapSet.new(metas, & &1["phx_ref"])
        %{"metas" => Enum.reject(current, &(&1["phx_ref"] in new)) ++ metas}
      end)
    end)
  end

  defp leave(state, leaves) do
    Enum.reduce(leaves, state, fn {key, %{"metas" => metas}}, state ->
      gone = MapSet.new(metas, & &1["phx_ref"])

      case Map.fetch(state, key) do
        {:ok, %{"metas" => current}} ->
          case Enum.reject(current, &(&1["phx_ref"] in gone)) do
            [] -> Map.delete(state, key)
            left -> Map.put(state, key, %{"metas" => left})
          end

        :error ->
          state
      end
    end)
  end

  defp refs(state),
    do:
      Map.new(state, fn {key, %{"metas" => metas}} ->
        {key, MapSet.new(metas, & &1["phx_ref"])}
      end)

  defp stringify(presences) do
    Map.new(presences, fn {key, %{metas: metas}} ->
      {key, %{"metas" => Enum.map(metas, &%{"phx_ref" => &1.phx_ref})}}
    end)
  end
end
