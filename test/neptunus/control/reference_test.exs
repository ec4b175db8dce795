defmodule Neptunus.Control.ReferenceTest do
  use ExUnit.Case, async: true

  alias Neptunus.Control.Reference
  alias Neptunus.PID
  alias Neptunus.Test.Properties

  doctest Reference

  @pi :math.pi()
  @dt 0.02

  # the reference's trajectory over `n` steps towards `setpoint`
  defp run(ref, setpoint, n \\ 1_000) do
    {traj, _} =
      Enum.map_reduce(1..n, ref, fn _, ref ->
        ref = Reference.step(ref, setpoint, @dt)
        {ref, ref}
      end)

    traj
  end

  test "a 1 m step: bounded rate and acceleration, arrives at rest without overshoot" do
    ref = Reference.new(0.0, rate: 0.3, accel: 0.2)
    traj = run(ref, 1.0)
    rates = [0.0 | Enum.map(traj, & &1.rate)]

    assert Enum.all?(rates, &(abs(&1) <= 0.3 + 1.0e-12))

    assert rates
           |> Enum.chunk_every(2, 1, :discard)
           |> Enum.all?(fn [a, b] -> abs(b - a) / @dt <= 0.2 + 1.0e-9 end)

    assert Enum.max(Enum.map(traj, & &1.value)) <= 1.0 + 1.0e-4
    assert %{value: 1.0, rate: +0.0} = List.last(traj)
    # it gets there: accelerate, cruise, brake (≈ 1/0.3 + 0.3/0.2 s)
    arrived = Enum.find_index(traj, &(&1.value == 1.0 and &1.rate == 0.0))
    assert arrived * @dt < 6.0
  end

  test "an angle turns the short way across north and stays in [0, 2π)" do
    ref = Reference.new(350 * @pi / 180, rate: 0.4, accel: 0.3, wrap: true)
    traj = run(ref, 10 * @pi / 180)
    assert hd(traj).rate > 0
    assert Enum.all?(traj, &(&1.value >= 0 and &1.value < 2 * @pi))
    assert_in_delta List.last(traj).value, 10 * @pi / 180, 1.0e-12
  end

  test "a setpoint changed mid-move: the rate stays continuous" do
    ref = Reference.new(0.0, rate: 0.3, accel: 0.2)
    ref = ref |> run(2.0, 200) |> List.last()
    assert ref.rate > 0.2
    # the setpoint goes back behind it: it brakes at the acceleration limit, no jump
    next = Reference.step(ref, 0.0, @dt)
    assert_in_delta next.rate, ref.rate - 0.2 * @dt, 1.0e-12
  end

  test "bad limits are refused" do
    assert Reference.validate(rate: 0.3, accel: 0.2) == :ok

    assert Reference.validate(rate: 0, accel: 0.2) ==
             {:error, "reference rate must be a number > 0, got 0"}

    assert Reference.validate(rate: 1) ==
             {:error, "reference accel must be a number > 0, got nothing"}

    assert_raise ArgumentError, fn -> Reference.new(0.0, rate: -1, accel: 1) end
  end

  test "property: under any sequence of setpoints the limits hold and it settles on the last" do
    gen =
      :proper_types.tuple([
        :proper_types.float(0.01, 2.0),
        :proper_types.float(0.01, 2.0),
        :proper_types.boolean(),
        :proper_types.non_empty(:proper_types.list(:proper_types.float(-10.0, 10.0)))
      ])

    Properties.check(
      gen,
      fn {rate, accel, wrap, setpoints} ->
        ref = Reference.new(0.0, rate: rate, accel: accel, wrap: wrap)

        # each setpoint for 0.5 s, then the last one until it settles
        {ref, ok?} =
          Enum.reduce(setpoints, {ref, true}, fn sp, {ref, ok?} ->
            Enum.reduce(1..25, {ref, ok?}, fn _, {ref, ok?} ->
              next = Reference.step(ref, sp, @dt)

              ok? =
                ok? and abs(next.rate) <= rate + 1.0e-9 and
                  abs(next.rate - ref.rate) <= accel * @dt + 1.0e-9 and
                  (not wrap or (next.value >= 0 and next.value < 2 * @pi))

              {next, ok?}
            end)
          end)

        last = List.last(setpoints)
        # long enough to stop, come back and cross the distance at the rate limit
        distance = abs(last - ref.value) + abs(ref.rate) * ref.rate / accel
        steps = trunc((distance / rate + 2 * rate / accel + 5) / @dt) + 1
        settled = ref |> run(last, steps) |> List.last()

        target = if wrap, do: PID.wrap_2pi(last), else: last

        ok? and settled.rate == 0.0 and abs(settled.value - target) < 1.0e-9
      end,
      100
    )
  end
end
