defmodule Neptunus.VehicleTest do
  # Processes of one vehicle, with the real simulated board, under the test's supervisor.
  # The helm runs on an injected clock (an Agent the test moves by hand) and never ticks on
  # its own, so the deadman is tested without measuring wall time.
  use ExUnit.Case, async: true

  alias Neptunus.{Allocation, Fleet, PubSub}
  alias Neptunus.Vehicle.{Board, Control, Helm, Telemetry}

  @moduletag :capture_log

  setup context do
    id = "t-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))
    PubSub.subscribe(Telemetry.log_topic(id))
    clock = start_supervised!({Agent, fn -> 0 end})

    helm = [
      clock: fn -> Agent.get(clock, & &1) end,
      tick_ms: 3_600_000,
      request_timeout_ms: Map.get(context, :request_timeout_ms, 10_000),
      takeover_ms: Map.get(context, :takeover_ms, 3_000)
    ]

    start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated, helm: helm}})
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
    {:ok, id: id, clock: clock}
  end

  defp motion(s, h, y), do: %{"mode" => "motion", "surge" => s, "heave" => h, "yaw" => y}

  # A party: a process standing for one connection, whose targeted events reach the test as
  # {:notify, name, event, payload}.
  defp party(name, role \\ :pilot) do
    test = self()
    pid = spawn(fn -> receive do: (:die -> :ok) end)

    %{
      id: "#{name}-#{System.unique_integer([:positive])}",
      name: name,
      role: role,
      pid: pid,
      notify: fn event, payload -> send(test, {:notify, name, event, payload}) end
    }
  end

  defp pilot!(id, party) do
    assert {:ok, %{status: "granted", grant: %{epoch: epoch}}} = Helm.request_control(id, party)
    assert_receive {:notify, _, "control_granted", %{epoch: ^epoch}}
    epoch
  end

  defp board_thrusters(id), do: Board.Simulated.state(id).sim.thrusters
  defp advance(clock, ms), do: Agent.update(clock, &(&1 + ms))

  test "telemetry reaches every connection, the prioritized one first, observers in slices" do
    id = "paced-#{System.unique_integer([:positive])}"
    topic = Telemetry.topic(id)
    test = self()

    subscribe = fn name, first? ->
      spawn_link(fn ->
        PubSub.subscribe_fastlane(topic)
        if first?, do: PubSub.prioritize(topic, true)
        send(test, {:subscribed, name})
        telemetry = ~s([null,null,"#{topic}","telemetry")

        receive do
          {:pubsub_frame, ^topic, "telemetry",
           <<^telemetry::binary-size(byte_size(telemetry)), _::binary>> = frame} ->
            send(test, {:frame, name, frame})
        end
      end)

      assert_receive {:subscribed, ^name}
    end

    subscribe.(:pilot, true)
    for name <- 1..7, do: subscribe.(name, false)

    start_supervised!(
      {Neptunus.Vehicle.Supervisor,
       %{id: id, board: :simulated, fanout_slice: 2, fanout_gap_ms: 5}},
      id: :paced
    )

    assert_receive {:frame, :pilot, frame}
    names = for _ <- 1..7, do: assert_receive({:frame, name, ^frame}, 1_000) && name
    assert Enum.sort(names) == Enum.to_list(1..7)
    assert [:null, :null, ^topic, "telemetry", %{"t" => _}] = :jiffy.decode(frame, [:return_maps])
  end

  test "telemetry arrives at the configured rate with the documented shape", %{id: id} do
    assert_receive {:pubsub, _, "telemetry", first}
    assert %{t: t, sent_at: sent_at, measurement: m, sim: sim, command: c, thrusters: thr} = first
    assert is_float(t) and is_float(sent_at)
    assert Map.keys(m) |> Enum.sort() == ~w(current depth heading pitch roll voltage)a
    assert Map.keys(sim) |> Enum.sort() == ~w(p phi psi q r theta u v w x y z)a
    assert c == %{surge: 0.0, heave: 0.0, yaw: 0.0}
    assert %{port: +0.0, port_us: 1500, vertical_us: 1500, starboard_us: 1500} = thr
    # no first reading is trusted: each measurement says whether it is valid yet
    assert Map.keys(first.measurement_state) |> Enum.sort() == Map.keys(m) |> Enum.sort()
    assert is_float(sim.z)
    # the built-in simulator has no link to lose
    assert first.link == %{up: true, reason: "no link"}

    # 20 Hz: ten more (their pace is for bench/, this only checks it runs)
    for _ <- 1..10, do: assert_receive({:pubsub, _, "telemetry", _})
    assert Telemetry.latest(id).t >= t
  end

  describe "control" do
    test "drives the board through eq. 9.3", %{id: id} do
      assert {:ok, %{command: cmd, thrusters: thr}} = Control.thrust(id, motion(1, 0, 0.5))
      assert cmd == %{surge: 1.0, heave: 0.0, yaw: 0.5}
      # gain 0.5: port sat(0.5*(1+0.5)) = 0.75, starboard 0.5*(1-0.5) = 0.25
      assert thr == Allocation.with_us(Allocation.motion(cmd, 0.5))
      assert %{port_us: 1875, vertical_us: 1500, starboard_us: 1625} = thr
      assert_in_delta thr.port, 0.75, 1.0e-12
      assert_in_delta thr.starboard, 0.25, 1.0e-12
      assert board_thrusters(id) == Map.take(thr, [:port, :vertical, :starboard])
      assert %{gain: 0.5, mode: "motion", command: ^cmd} = Control.status(id)
    end

    test "bad commands are refused with a reason and change nothing", %{id: id} do
      {:ok, before} = Control.thrust(id, motion(0.3, 0.1, 0))

      for {params, reason} <- [
            {motion(2, 0, 0), ~r/surge must be a number in \[-1, 1\]/},
            {motion("1", 0, 0), ~r/surge must be a number/},
            {Map.delete(motion(0, 0, 0), "yaw"), ~r/missing field: yaw/},
            {Map.put(motion(0, 0, 0), "roll", 1), ~r/unknown field: roll/},
            {%{"mode" => "manual", "port" => 0, "vertical" => 0, "starboard" => 0},
             ~r/thrust mode manual does not match control mode motion/},
            {%{motion(0, 0, 0) | "mode" => "dp"}, ~r/mode must be "motion" or "manual"/},
            {Map.delete(motion(0, 0, 0), "mode"), ~r/missing field: mode/}
          ] do
        assert {:error, message} = Control.thrust(id, params)
        assert message =~ reason
      end

      assert board_thrusters(id) == Map.take(before.thrusters, [:port, :vertical, :starboard])
    end

    test "stop goes neutral and tells everyone why, on the vehicle and in the log", %{id: id} do
      {:ok, _} = Control.thrust(id, motion(1, 1, 1))
      assert {:ok, %{thrusters: thr}} = Control.stop(id, "window_blur")
      assert thr == Allocation.with_us(Allocation.neutral())
      assert_receive {:pubsub, _, "stopped", %{reason: "window_blur"}}
      assert_receive {:pubsub, "log:" <> _, "log", %{category: "safety", reason: "window_blur"}}
      assert board_thrusters(id) == Allocation.neutral()
    end
  end

  describe "helm" do
    test "a free helm grants at once; the grant carries the epoch and the control state", ctx do
      ada = party("ada")

      %{epoch: free} = Helm.status(ctx.id)
      assert {:ok, %{status: "granted", grant: grant}} = Helm.request_control(ctx.id, ada)
      epoch = free + 1
      assert %{epoch: ^epoch, pilot: %{name: "ada", role: "pilot"}, deadman_ms: 500} = grant
      assert %{mode: "motion", gain: 0.5, command: %{surge: +0.0}} = grant.control
      assert_receive {:notify, "ada", "control_granted", ^grant}

      assert_receive {:pubsub, _, "helm",
                      %{state: "piloted", pilot: %{name: "ada"}, epoch: ^epoch}}

      assert {:ok, %{thrusters: %{port: 0.5}}} =
               Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))

      assert {:error, "missing field: epoch"} = Helm.thrust(ctx.id, ada, motion(1, 0, 0))

      assert {:error, "stale_command"} =
               Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", free))
    end

    test "only the pilot commands; observers and others change nothing", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, before} = Helm.thrust(ctx.id, ada, Map.put(motion(0.2, 0, 0), "epoch", epoch))
      bob = party("bob")
      olga = party("olga", :observer)

      for who <- [bob, olga] do
        assert Helm.thrust(ctx.id, who, Map.put(motion(-1, 0, 0), "epoch", epoch)) ==
                 {:error, "not_in_control"}

        assert Helm.stop(ctx.id, who, "meddling") == {:error, "not_in_control"}
        assert Helm.heartbeat(ctx.id, who) == {:error, "not_in_control"}
        assert Helm.release_control(ctx.id, who) == {:error, "not_in_control"}
        assert Helm.answer_request(ctx.id, who, true) == {:error, "not_in_control"}

        assert Helm.command(ctx.id, who, :none, fn -> flunk("ran for a non-pilot") end) ==
                 {:error, "not_in_control"}
      end

      assert Helm.request_control(ctx.id, olga) == {:error, "forbidden"}
      assert Helm.take_control(ctx.id, bob) == {:error, "forbidden"}
      assert board_thrusters(ctx.id) == Map.take(before.thrusters, [:port, :vertical, :starboard])
      refute_received {:pubsub, _, "stopped", _}
    end

    test "request, accept: neutral on transfer, and the old pilot's commands are refused", ctx do
      ada = party("ada")
      bob = party("bob")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))

      assert {:ok, %{status: "pending", timeout_ms: t}} = Helm.request_control(ctx.id, bob)
      assert t > 9_000
      assert_receive {:notify, "ada", "control_request", %{from: %{name: "bob", role: "pilot"}}}
      assert_receive {:pubsub, _, "helm", %{state: "requested", request: %{from: %{name: "bob"}}}}
      assert Helm.request_control(ctx.id, party("cy")) == {:error, "busy"}

      assert {:ok, %{helm: %{state: "piloted"}}} = Helm.answer_request(ctx.id, ada, true)
      assert_receive {:pubsub, _, "stopped", %{reason: "control_transferred"}}
      assert_receive {:notify, "ada", "control_lost", %{reason: "control_transferred"}}
      assert_receive {:notify, "bob", "control_granted", %{epoch: new_epoch, control: control}}
      assert new_epoch == epoch + 1
      assert control.command == %{surge: 0.0, heave: 0.0, yaw: 0.0}
      assert board_thrusters(ctx.id) == Allocation.neutral()

      assert {:error, "not_in_control"} =
               Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))

      # bob's stick was pushed before he heard of the grant: stale
      assert {:error, "stale_command"} =
               Helm.thrust(ctx.id, bob, Map.put(motion(1, 0, 0), "epoch", epoch))

      assert board_thrusters(ctx.id) == Allocation.neutral()
      assert {:ok, _} = Helm.thrust(ctx.id, bob, Map.put(motion(0.5, 0, 0), "epoch", new_epoch))
    end

    test "request, deny: the requester is told, the pilot keeps flying", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, before} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))
      bob = party("bob")
      {:ok, %{status: "pending"}} = Helm.request_control(ctx.id, bob)
      assert {:ok, _} = Helm.answer_request(ctx.id, ada, false)
      assert_receive {:notify, "bob", "request_denied", %{reason: "denied"}}
      assert Helm.answer_request(ctx.id, ada, true) == {:error, "no_request"}
      assert board_thrusters(ctx.id) == Map.take(before.thrusters, [:port, :vertical, :starboard])
      assert %{state: "piloted", pilot: %{name: "ada"}, epoch: ^epoch} = Helm.status(ctx.id)
    end

    @tag request_timeout_ms: 50
    test "an unanswered request times out", ctx do
      ada = party("ada")
      pilot!(ctx.id, ada)
      {:ok, %{status: "pending"}} = Helm.request_control(ctx.id, party("bob"))
      assert_receive {:notify, "bob", "request_denied", %{reason: "request_timeout"}}
      assert_receive {:pubsub, _, "helm", %{state: "piloted", request: nil}}
    end

    @tag takeover_ms: 50
    test "the main station takes control after a warning countdown", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))
      main = party("main", :main_station)

      assert {:ok, %{status: "takeover", countdown_ms: ms}} = Helm.take_control(ctx.id, main)
      assert ms in 1..50

      assert_receive {:pubsub, _, "helm",
                      %{state: "takeover", takeover: %{by: %{name: "main"}, countdown_ms: _}}}

      # the pilot flies until the transfer
      assert {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(0.5, 0, 0), "epoch", epoch))

      assert_receive {:notify, "main", "control_granted", %{epoch: new_epoch}}
      assert new_epoch == epoch + 1
      assert_receive {:pubsub, _, "stopped", %{reason: "main_station_takeover"}}
      assert_receive {:notify, "ada", "control_lost", %{reason: "main_station_takeover"}}
      assert board_thrusters(ctx.id) == Allocation.neutral()

      assert %{state: "piloted", pilot: %{name: "main", role: "main_station"}} =
               Helm.status(ctx.id)
    end

    test "the pilot's death stops the vehicle and frees the helm", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))
      send(ada.pid, :die)
      assert_receive {:pubsub, _, "stopped", %{reason: "pilot_disconnected"}}
      assert_receive {:pubsub, _, "helm", %{state: "free", pilot: nil}}
      assert board_thrusters(ctx.id) == Allocation.neutral()
      assert {:ok, %{status: "granted"}} = Helm.request_control(ctx.id, party("bob"))
    end

    test "the pilot's death with a request pending hands the helm to the requester", ctx do
      ada = party("ada")
      pilot!(ctx.id, ada)
      {:ok, %{status: "pending"}} = Helm.request_control(ctx.id, party("bob"))
      send(ada.pid, :die)
      assert_receive {:pubsub, _, "stopped", %{reason: "pilot_disconnected"}}
      assert_receive {:notify, "bob", "control_granted", _}
    end

    test "release stops the vehicle and frees the helm", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))
      assert {:ok, %{helm: %{state: "free"}}} = Helm.release_control(ctx.id, ada)
      assert_receive {:pubsub, _, "stopped", %{reason: "released"}}
      assert_receive {:notify, "ada", "control_lost", %{reason: "released"}}
      assert board_thrusters(ctx.id) == Allocation.neutral()
    end

    test "deadman: the pilot's silence stops the vehicle, once; only a fresh command moves it",
         ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))

      # heartbeats every 100 ms (of the injected clock) keep it going
      for _ <- 1..20 do
        advance(ctx.clock, 100)
        assert {:ok, %{}} = Helm.heartbeat(ctx.id, ada)
        :ok = Helm.check_deadman(ctx.id)
      end

      refute_received {:pubsub, _, "stopped", _}
      refute board_thrusters(ctx.id) == Allocation.neutral()

      # someone else's heartbeats do not count (ArduSub #17724)
      helper = party("helper")

      for _ <- 1..5 do
        advance(ctx.clock, 100)
        assert {:error, "not_in_control"} = Helm.heartbeat(ctx.id, helper)
      end

      advance(ctx.clock, 1)
      :ok = Helm.check_deadman(ctx.id)
      assert_receive {:pubsub, _, "stopped", %{reason: "deadman"}}
      tripped_epoch = epoch + 1
      assert_receive {:pubsub, _, "helm", %{state: "piloted", epoch: ^tripped_epoch}}
      assert board_thrusters(ctx.id) == Allocation.neutral()

      # silent on: no second stop
      advance(ctx.clock, 10_000)
      :ok = Helm.check_deadman(ctx.id)
      refute_received {:pubsub, _, "stopped", _}

      # the pilot is back: heartbeats alone do not bring the thrust back, and a command made
      # before the client heard of the trip is stale
      assert {:ok, %{}} = Helm.heartbeat(ctx.id, ada)

      assert {:error, "stale_command"} =
               Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))

      assert board_thrusters(ctx.id) == Allocation.neutral()
      assert {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", tripped_epoch))
      refute board_thrusters(ctx.id) == Allocation.neutral()
    end

    test "a crashed control restarts the helm too: thrusters neutral, helm free", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))
      old = Fleet.whereis(Control, ctx.id)
      ref = Process.monitor(old)
      Process.exit(old, :kill)
      assert_receive {:DOWN, ^ref, :process, _, :killed}
      assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
      assert %{state: "free"} = Helm.status(ctx.id)
      assert board_thrusters(ctx.id) == Allocation.neutral()
    end

    test "a crashed helm restarts, stops the vehicle and forgets the pilot", ctx do
      ada = party("ada")
      epoch = pilot!(ctx.id, ada)
      {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch))
      old = Fleet.whereis(Helm, ctx.id)
      Process.exit(old, :kill)
      assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
      assert_receive {:pubsub, _, "helm", %{state: "free"}}
      assert board_thrusters(ctx.id) == Allocation.neutral()

      assert Helm.thrust(ctx.id, ada, Map.put(motion(1, 0, 0), "epoch", epoch)) ==
               {:error, "not_in_control"}
    end
  end

  test "the simulated vehicle moves forward under surge and dives under heave", ctx do
    start = Board.Simulated.state(ctx.id).sim.dyn
    ada = party("ada")
    epoch = pilot!(ctx.id, ada)
    {:ok, _} = Helm.thrust(ctx.id, ada, Map.put(motion(1, 1, 0), "epoch", epoch))

    # as the simulation advances (it keeps pace with the clock, and skips what a stalled
    # machine could not step): forward and down
    Neptunus.Test.Pty.wait_until(
      fn ->
        now = Board.Simulated.state(ctx.id).sim.dyn
        now.u > 0.2 and now.x > start.x and now.z > start.z and now.w > 0.0
      end,
      "the vehicle moving forward and down"
    )
  end
end
