defmodule Neptunus.Control.TuningTest do
  use ExUnit.Case, async: true

  alias Neptunus.Control.{Autopilot, Core, Tuning}
  alias Neptunus.PID
  alias Neptunus.Test.Properties

  doctest PID, only: [retune: 5]
  doctest Tuning

  describe "validate" do
    test "an axis, some gains: only those" do
      assert Tuning.validate(%{"depth" => %{"kp" => 2, "kd" => 1.5}}) ==
               {:ok, %{depth: [kd: 1.5, kp: 2.0]}}

      assert {:ok, %{depth: [ki: +0.0], heading: [kd: 20.0, ki: 5.0, kp: 0.5]}} =
               Tuning.validate(%{
                 "depth" => %{"ki" => 0},
                 "heading" => %{"kp" => 0.5, "ki" => 5, "kd" => 20}
               })
    end

    test "errors name the field and change nothing" do
      assert Tuning.validate(%{"depth" => %{"kp" => 30}}) ==
               {:error, "depth.kp must be a number in [0, 20], got 30"}

      assert Tuning.validate(%{"heading" => %{"ki" => -1}}) ==
               {:error, "heading.ki must be a number in [0, 5], got -1"}

      assert Tuning.validate(%{"depth" => %{"kd" => "1"}}) ==
               {:error, ~s(depth.kd must be a number in [0, 20], got "1")}

      assert Tuning.validate(%{"surge" => %{"kp" => 1}}) ==
               {:error, "unknown field: tuning.surge"}

      assert Tuning.validate(%{"depth" => %{"kx" => 1}}) == {:error, "unknown field: depth.kx"}
      assert Tuning.validate(%{}) == {:error, "tuning needs depth and/or heading"}
      assert Tuning.validate(%{"depth" => %{}}) == {:error, "depth needs kp, ki and/or kd"}
      assert Tuning.validate(%{"depth" => 1}) == {:error, "depth must be an object, got 1"}
      assert Tuning.validate([1]) == {:error, "tuning must be an object, got a list"}
    end

    test "property: any JSON-like payload is either valid gains in range or an error" do
      gain = :proper_types.oneof([:proper_types.float(-5.0, 30.0), Properties.json_leaf()])

      key =
        :proper_types.oneof([
          :proper_types.exactly("kp"),
          :proper_types.exactly("ki"),
          :proper_types.exactly("kd"),
          :proper_types.exactly("x")
        ])

      axis =
        :proper_types.oneof([
          :proper_types.exactly("depth"),
          :proper_types.exactly("heading"),
          :proper_types.exactly("roll")
        ])

      pairs = fn k, v -> :proper_types.list(:proper_types.tuple([k, v])) end
      payload = pairs.(axis, pairs.(key, gain))

      Properties.check(payload, fn pairs ->
        payload = Map.new(pairs, fn {axis, gains} -> {axis, Map.new(gains)} end)

        case Tuning.validate(payload) do
          {:ok, gains} ->
            Enum.all?(gains, fn {_axis, kw} ->
              Enum.all?(kw, fn {k, v} ->
                {lo, hi} = Tuning.ranges()[Atom.to_string(k)]
                is_float(v) and v >= lo and v <= hi
              end)
            end)

          {:error, reason} ->
            is_binary(reason)
        end
      end)
    end
  end

  test "merge and JSON" do
    merged = Tuning.merge(Core.default_gains(), %{depth: [kp: 1.0]})
    assert merged.depth == [kp: 1.0, ki: 0.1, kd: 1.5]

    assert Tuning.to_json(merged) == %{
             "depth" => %{"kp" => 1.0, "ki" => 0.1, "kd" => 1.5},
             "heading" => %{"kp" => 4.0, "ki" => 0.3, "kd" => 2.0}
           }

    {:ok, back} = Tuning.validate(Tuning.to_json(merged))
    assert Tuning.merge(Core.default_gains(), back) == merged
  end

  describe "bumpless retune" do
    test "property: the output of a holding autopilot does not jump when its gains change" do
      gains = fn ->
        :proper_types.tuple([
          :proper_types.float(0.0, 20.0),
          :proper_types.float(0.0, 5.0),
          :proper_types.float(0.0, 20.0)
        ])
      end

      gen =
        :proper_types.tuple([
          gains.(),
          :proper_types.float(0.0, 3.0),
          :proper_types.float(-0.5, 0.5),
          :proper_types.float(-0.3, 0.3)
        ])

      Properties.check(gen, fn {{kp, ki, kd}, setpoint, offset, rate} ->
        measured = setpoint + offset
        ap = Autopilot.new(:depth, Core.default_gains().depth)
        ap = Autopilot.engage(ap, :hold, setpoint, 0.0, false)
        # integral learnt, reference settled at the setpoint, vehicle off it and moving
        ap = Enum.reduce(1..20, ap, fn _, ap -> Autopilot.step(ap, measured, rate, 0.02) end)
        before = Autopilot.output(ap)
        tuned = Autopilot.retune(ap, [kp: kp, ki: ki, kd: kd], measured, rate)
        # the next output at the same measurement (no time passed) is the one before
        after_ = tuned |> Autopilot.step(measured, rate, 0.0) |> Autopilot.output()
        saturated? = abs(before) >= 1.0 or abs(tuned.pid.integral) >= 1.0

        Autopilot.gains(tuned) == [kp: kp, ki: ki, kd: kd] and
          (saturated? or abs(after_ - before) < 1.0e-9)
      end)
    end

    test "core: applied to the axes given, recorded in the core's gains" do
      core =
        Core.new()
        |> Core.estimate(
          %{t: 1.0, depth: 2.0, depth_rate: 0.1, heading: 1.0, yaw_rate: 0.0, position: nil},
          10.0
        )

      {:ok, core, _} = Core.command(core, {:autopilot, %{depth: 2.3, heading: :unchanged}}, 10.0)
      {core, _} = Core.tick(core, 0.02, 10.02)
      before = core.thrusters
      core = Core.retune(core, %{depth: [kp: 9.0, kd: 0.5]})
      assert core.gains.depth == [kp: 9.0, ki: 0.1, kd: 0.5]
      assert core.gains.heading == Core.default_gains().heading
      assert Autopilot.gains(core.depth) == [kp: 9.0, ki: 0.1, kd: 0.5]
      assert_in_delta Core.mix(core).vertical, before.vertical, 1.0e-9
    end
  end

  describe "step response" do
    test "requests are validated" do
      assert {:ok, :depth, 1.0, %{}} = Tuning.validate_step(%{"axis" => "depth", "step" => 1})

      assert {:ok, :heading, 1.5, %{heading: [kp: 2.0]}} =
               Tuning.validate_step(%{
                 "axis" => "heading",
                 "step" => 1.5,
                 "gains" => %{"heading" => %{"kp" => 2}}
               })

      assert Tuning.validate_step(%{"axis" => "roll", "step" => 1}) ==
               {:error, ~s(axis must be "depth" or "heading", got "roll")}

      assert Tuning.validate_step(%{"axis" => "depth", "step" => 0}) ==
               {:error, "step must be a non-zero number in [-10.0, 10.0], got 0"}

      assert Tuning.validate_step(%{"axis" => "depth"}) ==
               {:error, "step_response needs axis and step"}

      assert Tuning.validate_step(%{
               "axis" => "depth",
               "step" => 1,
               "gains" => %{"depth" => %{"kp" => 99}}
             }) ==
               {:error, "depth.kp must be a number in [0, 20], got 99"}
    end

    test "the default gains meet the acceptance figures; a poor tuning shows it" do
      control = [gains: Core.default_gains()]
      {:ok, r} = Tuning.step_response("neptunus", :depth, 1.0, control)
      assert r.axis == "depth" and r.target == 2.0
      assert length(r.t) == length(r.value) and length(r.t) == length(r.reference)
      assert r.overshoot < 0.10 and r.settle < 10.0

      {:ok, h} = Tuning.step_response("neptunus", :heading, :math.pi() / 2, control)
      assert h.settle < 8.0
      assert_in_delta List.last(h.value), :math.pi() / 2, 2 * :math.pi() / 180

      # a weak proportional gain and no damping: slow to settle
      weak = [gains: Tuning.merge(Core.default_gains(), %{depth: [kp: 0.3, ki: 0.0, kd: 0.0]})]
      {:ok, w} = Tuning.step_response("neptunus", :depth, 1.0, weak)
      assert w.settle == nil or w.settle > r.settle + 2
    end
  end
end
