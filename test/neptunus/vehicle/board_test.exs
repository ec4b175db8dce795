defmodule Neptunus.Vehicle.BoardTest do
  # The Board API and behaviour, with the test double that reports to the test process.
  use ExUnit.Case, async: true

  @moduletag :capture_log

  alias Neptunus.{Allocation, Fleet}
  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  setup do
    id = "board-#{System.unique_integer([:positive])}"

    start_supervised!(
      {Neptunus.Vehicle.Supervisor, %{id: id, board: Board.Test, report_to: self()}}
    )

    {:ok, id: id}
  end

  test "board types map to modules; a module stands for itself" do
    assert Board.module(:simulated) == Board.Simulated
    assert Board.module(:uart) == Board.OpenROV.UART
    assert Board.module(:sitl) == Board.OpenROV.SITL
    assert Board.module(Board.Test) == Board.Test
  end

  test "the board starts neutral and control drives it neutral on start", %{id: id} do
    neutral = Allocation.neutral()
    assert_receive {:board, ^id, {:started, ^neutral}}
    assert_receive {:board, ^id, {:go, ^neutral}}
  end

  test "control tells the board it is alive, right away and again after a restart", %{id: id} do
    assert_receive {:board, ^id, :keepalive}
    control = Fleet.whereis(Control, id)
    Process.exit(control, :kill)
    assert_receive {:board, ^id, {:go, _neutral}}
    assert_receive {:board, ^id, :keepalive}
    assert Fleet.whereis(Control, id) not in [nil, control]
  end

  test "commands reach the board as given", %{id: id} do
    Board.go(id, %{port: 0.25, vertical: -1.0, starboard: 1.0})
    assert_receive {:board, ^id, {:go, %{port: 0.25, vertical: -1.0, starboard: 1.0}}}
  end

  test "link status: from the board when it has one; simulated boards have none", %{id: id} do
    assert Board.link_status(id) == %{up: true, reason: "test"}
    Board.Test.set_link(id, false, "unplugged")
    assert Board.link_status(id) == %{up: false, reason: "unplugged"}
    assert Board.link_status("neptunus-1") == %{up: true, reason: "no link"}
    assert Board.link_status("no-such-vehicle") == %{up: true, reason: "no link"}
    assert Board.keepalive("no-such-vehicle") == :ok
  end

  test "samples from the board reach the vehicle's telemetry", %{id: id} do
    m = %{depth: 1.0, heading: 0.5, roll: 0.0, pitch: 0.0, voltage: 12.0, current: 1.0}
    # valid once the readings agree past the settle time (no first reading is trusted)
    for i <- 0..30, do: Board.Test.sample(id, %{t: i * 0.05, measurement: m, sim: nil})
    assert %{t: 1.5, measurement: ^m, sim: nil} = Telemetry.latest(id)
  end
end
