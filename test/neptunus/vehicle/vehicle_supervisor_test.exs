defmodule Neptunus.Vehicle.SupervisorTest do
  # A crash in the control chain drives the thrusters neutral without waiting for the
  # recorder or the camera, and restarts neither.
  use ExUnit.Case, async: true

  @moduletag :capture_log
  @moduletag :tmp_dir

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Vehicle.{Board, Control, Recorder, Telemetry}

  test "a telemetry crash: neutral at once while the recorder is busy; recorder kept",
       %{tmp_dir: dir} do
    id = "vsup-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))
    {:ok, _} = Fleet.start_vehicle(%{id: id, board: :simulated, recording: [dir: dir]})
    on_exit(fn -> Fleet.stop_vehicle(id) end)
    # the helm's own stop as it starts
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}

    assert {:ok, _} =
             Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})

    assert Enum.any?(Map.values(Board.Simulated.state(id).sim.thrusters), &(&1 != 0))

    recorder = Fleet.whereis(Recorder, id)
    control = Fleet.whereis(Control, id)
    # a recorder busy (a disk that hangs a sync) until the test lets it go: it cannot stop
    # before then
    test = self()
    busy = make_ref()

    spawn(fn ->
      :sys.replace_state(
        recorder,
        fn s ->
          send(test, {busy, :busy})

          receive do
            {^busy, :go} -> s
          end
        end,
        :infinity
      )
    end)

    assert_receive {^busy, :busy}
    on_exit(fn -> send(recorder, {busy, :go}) end)

    Process.exit(Fleet.whereis(Telemetry, id), :kill)

    # the new Control says it stopped, and the board is neutral, while the recorder is still
    # busy
    assert_receive {:pubsub, _, "stopped", _}
    assert Fleet.whereis(Control, id) != control
    assert Enum.all?(Map.values(Board.Simulated.state(id).sim.thrusters), &(&1 == 0))
    assert Fleet.whereis(Recorder, id) == recorder
    send(recorder, {busy, :go})
  end

  test "a request while the helm restarts is refused with a reason, not an exit" do
    id = "vsup-helm-#{System.unique_integer([:positive])}"
    {:ok, _} = Fleet.start_vehicle(%{id: id, board: :simulated})
    on_exit(fn -> Fleet.stop_vehicle(id) end)

    chain =
      Fleet.whereis(Neptunus.Vehicle.Supervisor, id)
      |> Supervisor.which_children()
      |> Enum.find_value(fn {child, pid, _, _} ->
        child == Neptunus.Vehicle.Supervisor.Control && pid
      end)

    # the helm down and not yet restarted
    :ok = :sys.suspend(chain)
    helm = Fleet.whereis(Neptunus.Vehicle.Helm, id)
    ref = Process.monitor(helm)
    Process.exit(helm, :kill)
    assert_receive {:DOWN, ^ref, :process, ^helm, :killed}

    party = %{id: "p1", name: "pilot", role: :pilot, pid: self(), notify: fn _, _ -> :ok end}
    assert {:error, "vehicle restarting" <> _} = Neptunus.Vehicle.Helm.request_control(id, party)
    assert {:error, "vehicle restarting" <> _} = Neptunus.Vehicle.Helm.heartbeat(id, party)
    assert :ok = Neptunus.Vehicle.Helm.leave(id, "p1", "pilot_left")

    :ok = :sys.resume(chain)
  end
end
