defmodule Neptunus.Vehicle.BoardRegistryTest do
  # The boards, once: their types, how they are configured, what their vehicles can do.
  use ExUnit.Case, async: true

  alias Neptunus.Vehicle.Board

  doctest Neptunus.Vehicle.Board
  doctest Neptunus.Vehicle.Board.Simulated, only: [capabilities: 1]

  test "every board type has a module implementing the whole behaviour" do
    for type <- [:simulated, :sitl, :uart, :mavlink] do
      module = Board.module(type)
      assert Code.ensure_loaded?(module)

      for {callback, arity} <- [start_link: 1, capabilities: 1, go: 2],
          do: assert(function_exported?(module, callback, arity), "#{module}.#{callback}")
    end
  end

  test "what each vehicle can do" do
    assert %{axes: [:surge, :heave, :yaw], allocation: :thesis, real: false} =
             Board.capabilities(:simulated, [])

    for type <- [:sitl, :uart] do
      assert %{
               axes: [:surge, :heave, :yaw],
               allocation: :thesis,
               real: true,
               autopilots: :neptunus
             } = Board.capabilities(type, [])
    end

    assert %{axes: [:surge, :sway, :heave, :yaw], allocation: :vehicle, autopilots: :vehicle} =
             Board.capabilities(:mavlink, [])
  end

  test "telemetry's link details are the boards' own" do
    details = Board.link_details()
    assert :mavlink in details and :rtt_ms in details and :board_settings in details
    assert details == Enum.uniq(details)
  end

  test "a board without vehicle commands refuses them with a reason" do
    id = "none-#{System.unique_integer([:positive])}"
    me = self()
    notify = &send(me, &1)

    assert {:error, "this vehicle's board has no arming" <> _} =
             Board.command(id, {:arm, true}, notify)

    assert {:error, _} = Board.command(id, {:mode, "MANUAL"}, notify)
  end

  test "the axes a running board declares are the vehicle's while it lives; then the configured ones" do
    id = "axes-#{System.unique_integer([:positive])}"
    :ok = Board.register_capabilities(id, Board.capabilities(:mavlink, []))
    assert Board.capabilities(id).axes == [:surge, :sway, :heave, :yaw]

    me = self()

    board =
      spawn_link(fn ->
        :ok = Board.declare_axes(id, [:surge, :heave, :yaw])
        send(me, :declared)
        receive(do: (:vectored -> :ok = Board.declare_axes(id, [:surge, :sway, :heave, :yaw])))
        send(me, :declared)
        receive(do: (:stop -> :ok))
      end)

    assert_receive :declared
    assert %{axes: [:surge, :heave, :yaw], allocation: :vehicle} = Board.capabilities(id)
    send(board, :vectored)
    assert_receive :declared
    assert Board.capabilities(id).axes == [:surge, :sway, :heave, :yaw]

    ref = Process.monitor(board)
    send(board, :stop)
    assert_receive {:DOWN, ^ref, :process, _, _}
    # the registry forgets a process that is gone (its partition hears the exit)
    Neptunus.Test.Pty.wait_until(
      fn -> Registry.lookup(Neptunus.Fleet.Registry, {Board.Axes, id}) == [] end,
      "the declaration gone with its board"
    )

    assert Board.capabilities(id).axes == [:surge, :sway, :heave, :yaw]
  end
end
