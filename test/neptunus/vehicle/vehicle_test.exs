defmodule Neptunus.VehicleTest do
  # Processes of one vehicle, with the real simulated board, under the test's supervisor.
  use ExUnit.Case, async: true

  alias Neptunus.{Allocation, Fleet, PubSub}
  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  setup context do
    id = "t-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))
    start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated}})
    me = %{pid: self(), name: "tester"}
    {:ok, id: id, me: me, test: context.test}
  end

  defp motion(s, h, y), do: %{"mode" => "motion", "surge" => s, "heave" => h, "yaw" => y}

  defp other_caller do
    pid = spawn(fn -> Process.sleep(:infinity) end)
    %{pid: pid, name: "other"}
  end

  test "telemetry arrives at the configured rate with the documented shape", %{id: id} do
    assert_receive {:pubsub, _, "telemetry", first}, 500
    assert %{t: t, sent_at: sent_at, measurement: m, sim: sim, command: c, thrusters: thr} = first
    assert is_float(t) and is_float(sent_at)
    assert Map.keys(m) |> Enum.sort() == ~w(current depth heading pitch roll voltage)a
    assert Map.keys(sim) |> Enum.sort() == ~w(p phi psi q r theta u v w x y z)a
    assert c == %{surge: 0.0, heave: 0.0, yaw: 0.0}
    assert %{port: +0.0, port_us: 1500, vertical_us: 1500, starboard_us: 1500} = thr
    assert m.depth == sim.z

    # 20 Hz: ten more in about half a second (figures are for bench/, this only checks it runs)
    for _ <- 1..10, do: assert_receive({:pubsub, _, "telemetry", _}, 200)
    assert Telemetry.latest(id).t >= t
  end

  test "the first caller becomes pilot and drives the board through eq. 9.3", ctx do
    %{id: id, me: me} = ctx
    assert {:ok, %{command: cmd, thrusters: thr}} = Control.thrust(id, me, motion(1, 0, 0.5))
    assert cmd == %{surge: 1.0, heave: 0.0, yaw: 0.5}
    # gain 0.5: port sat(0.5*(1+0.5)) = 0.75, starboard 0.5*(1-0.5) = 0.25
    assert thr == Allocation.with_us(Allocation.motion(cmd, 0.5))
    assert %{port_us: 1875, vertical_us: 1500, starboard_us: 1625} = thr
    assert_in_delta thr.port, 0.75, 1.0e-12
    assert_in_delta thr.starboard, 0.25, 1.0e-12
    assert_receive {:pubsub, _, "pilot", %{pilot: %{name: "tester"}}}

    assert Board.Simulated.state(id).sim.thrusters ==
             Map.take(thr, [:port, :vertical, :starboard])

    assert %{pilot: %{name: "tester"}, gain: 0.5} = Control.status(id)
  end

  test "only the pilot commands; others change nothing", %{id: id, me: me} do
    {:ok, before} = Control.thrust(id, me, motion(0.2, 0, 0))
    other = other_caller()
    assert Control.thrust(id, other, motion(-1, 0, 0)) == {:error, "not_in_control"}
    assert Control.stop(id, other, "meddling") == {:error, "not_in_control"}

    assert Board.Simulated.state(id).sim.thrusters ==
             Map.take(before.thrusters, [:port, :vertical, :starboard])
  end

  test "bad commands are refused with a reason and change nothing", %{id: id, me: me} do
    {:ok, before} = Control.thrust(id, me, motion(0.3, 0.1, 0))

    for {params, reason} <- [
          {motion(2, 0, 0), ~r/surge must be a number in \[-1, 1\]/},
          {motion("1", 0, 0), ~r/surge must be a number/},
          {Map.delete(motion(0, 0, 0), "yaw"), ~r/missing field: yaw/},
          {Map.put(motion(0, 0, 0), "roll", 1), ~r/unknown field: roll/},
          {%{motion(0, 0, 0) | "mode" => "manual"}, ~r/control mode "manual" is not available/},
          {Map.delete(motion(0, 0, 0), "mode"), ~r/mode must be "motion"/}
        ] do
      assert {:error, message} = Control.thrust(id, me, params)
      assert message =~ reason
    end

    assert Board.Simulated.state(id).sim.thrusters ==
             Map.take(before.thrusters, [:port, :vertical, :starboard])
  end

  test "stop goes neutral and tells everyone why", %{id: id, me: me} do
    {:ok, _} = Control.thrust(id, me, motion(1, 1, 1))
    assert {:ok, %{thrusters: thr}} = Control.stop(id, me, "window_blur")
    assert thr == Allocation.with_us(Allocation.neutral())
    assert_receive {:pubsub, _, "stopped", %{reason: "window_blur"}}
    assert Board.Simulated.state(id).sim.thrusters == Allocation.neutral()
  end

  test "the pilot's death stops the vehicle and frees control", %{id: id} do
    test = self()

    pilot =
      spawn(fn ->
        send(test, Control.thrust(id, %{pid: self(), name: "doomed"}, motion(1, 0, 0)))
        receive do: (:die -> :ok)
      end)

    assert_receive {:ok, _}
    send(pilot, :die)
    assert_receive {:pubsub, _, "stopped", %{reason: "pilot_disconnected"}}
    assert_receive {:pubsub, _, "pilot", %{pilot: nil}}
    assert Board.Simulated.state(id).sim.thrusters == Allocation.neutral()
    assert {:ok, _} = Control.thrust(id, other_caller(), motion(0, 0, 0))
  end

  test "releasing control stops the vehicle; release by others is a no-op", %{id: id, me: me} do
    {:ok, _} = Control.thrust(id, me, motion(1, 0, 0))
    assert :ok = Control.release(id, other_caller(), "pilot_left")
    refute Board.Simulated.state(id).sim.thrusters == Allocation.neutral()
    assert :ok = Control.release(id, me, "pilot_left")
    assert_receive {:pubsub, _, "stopped", %{reason: "pilot_left"}}
    assert Board.Simulated.state(id).sim.thrusters == Allocation.neutral()
    assert Control.status(id).pilot == nil
  end

  test "a crashed control restarts and drives the thrusters neutral", %{id: id, me: me} do
    {:ok, _} = Control.thrust(id, me, motion(1, 0, 0))
    old = Fleet.whereis(Control, id)
    ref = Process.monitor(old)
    Process.exit(old, :kill)
    assert_receive {:DOWN, ^ref, :process, _, :killed}
    wait_until(fn -> Fleet.whereis(Control, id) not in [nil, old] end)
    # Control's handle_continue sends neutral before it answers anything
    assert Control.status(id).pilot == nil
    assert Board.Simulated.state(id).sim.thrusters == Allocation.neutral()
  end

  test "the simulated vehicle moves forward under surge and dives under heave", ctx do
    %{id: id, me: me} = ctx
    start = Board.Simulated.state(id).sim.dyn
    {:ok, _} = Control.thrust(id, me, motion(1, 1, 0))
    Process.sleep(600)
    now = Board.Simulated.state(id).sim.dyn
    assert now.u > 0.2
    assert now.x > start.x
    assert now.z > start.z
    assert now.w > 0.0
  end

  defp wait_until(fun, tries \\ 100) do
    cond do
      fun.() -> :ok
      tries == 0 -> flunk("condition not reached")
      true -> Process.sleep(10) && wait_until(fun, tries - 1)
    end
  end
end
