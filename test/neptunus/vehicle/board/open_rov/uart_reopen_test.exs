defmodule Neptunus.Vehicle.Board.OpenROV.UARTReopenTest do
  # The board link's port program dies while the vehicle moves: the link opens again at once
  # and writes neutral, instead of leaving the board on its last go() for the backoff.
  use ExUnit.Case, async: true

  @moduletag :uart
  @moduletag :capture_log

  import Neptunus.Test.Pty, only: [wait_until: 2]

  alias Neptunus.{Fleet, PubSub}
  alias Neptunus.Vehicle.Board.OpenROV.{SITL, Wiring}
  alias Neptunus.Vehicle.{Board, Control, Telemetry}

  test "a killed port program: the board is at neutral long before the backoff's 5 s" do
    id = "reopen-#{System.unique_integer([:positive])}"
    PubSub.subscribe(Telemetry.topic(id))

    {:ok, _} =
      Fleet.start_vehicle(%{
        id: id,
        board: :sitl,
        wiring: Wiring.default(),
        sim: [noise: false],
        reopen_min: 5_000,
        reopen_max: 10_000
      })

    on_exit(fn -> Fleet.stop_vehicle(id) end)
    assert_receive {:pubsub, _, "link", %{up: true}}
    # the helm's stop as it starts, before we drive
    assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
    # up for longer than reopen_min would need: only a link up a while reopens at once
    Process.sleep(200)

    assert {:ok, _} =
             Control.thrust(id, %{"mode" => "motion", "surge" => 1, "heave" => 0, "yaw" => 0})

    neutral = {1500, 1500, 1500}

    wait_until(
      fn -> SITL.Device.state(id).firmware.target_us != neutral end,
      "the board to drive"
    )

    {:os_pid, os_pid} = :sys.get_state(Fleet.whereis(Board, id)).port |> Port.info(:os_pid)
    {_, 0} = System.cmd("kill", ["-KILL", Integer.to_string(os_pid)])

    assert_receive {:pubsub, _, "link", %{up: false}}
    assert_receive {:pubsub, _, "link", %{up: true}}

    wait_until(
      fn -> SITL.Device.state(id).firmware.target_us == neutral end,
      "the board at neutral"
    )
  end
end
