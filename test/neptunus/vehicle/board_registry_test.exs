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
end
