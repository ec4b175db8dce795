defmodule Neptunus.Sim.FiniteTest do
  # The simulated vehicle stays finite for every input `sim_set` accepts: any current within
  # the validated ranges, any tether length, any thrust. The C loop takes the same sub-steps
  # as the Elixir one, bit for bit.
  use ExUnit.Case, async: true

  alias Neptunus.{Dynamics, Sim}
  alias Neptunus.Dynamics.{Native, State}
  alias Neptunus.Sim.Live
  alias Neptunus.Test.Properties

  @vehicles ["neptunus", "thesis-4dof"]
  # 3 s of simulated time at the default dt
  @steps 300

  # a number in [lo, hi], or one of `edges` (the accepted range's ends, where trouble is,
  # and the first refused values) as likely as the inside
  defp number(lo, hi, edges) do
    :proper_types.oneof([
      :proper_types.float(lo * 1.0, hi * 1.0),
      :proper_types.oneof(edges)
    ])
  end

  defp current, do: number(-5.5, 5.5, [-5, 5, 0, -5.5, 5.5])

  defp thrust, do: :proper_types.float(-1.0, 1.0)

  # sim_set payloads slightly beyond the accepted ranges too: those must be refused
  defp input do
    {:proper_types.oneof(@vehicles), [current(), current(), current()],
     number(-10, 1050, [1000, 0, 1000.5, -1]), {thrust(), thrust(), thrust()}}
  end

  defp finite?(%State{} = s) do
    s |> State.to_tuple() |> Tuple.to_list() |> Enum.all?(&(is_float(&1) and abs(&1) < 1.0e6))
  end

  defp run(vehicle, current, tether, {port, vertical, starboard}, opts) do
    ([vehicle: vehicle, current: current, tether_length: tether] ++ opts)
    |> Sim.new()
    |> Sim.command(%{port: port, vertical: vertical, starboard: starboard})
    |> Sim.step(@steps)
  end

  test "every accepted sim_set keeps the model finite, in Elixir and in C alike" do
    Properties.check(
      input(),
      fn {vehicle, current, tether, thrust} ->
        payload = %{"current" => current, "tether_length" => tether}

        case Live.validate("sim_set", payload) do
          {:ok, {:set, %{current: c, tether_length: l}}} ->
            elixir = run(vehicle, c, l, thrust, [])
            native = run(vehicle, c, l, thrust, native: true)
            finite?(elixir.dyn) and (not Native.available?() or native.dyn == elixir.dyn)

          {:error, reason} ->
            # refused: only outside the ranges
            is_binary(reason) and
              (Enum.any?(current, &(abs(&1) > 5)) or tether < 0 or tether > 1000)
        end
      end,
      60
    )
  end

  test "the corners: the strongest currents with the longest tether, full thrust" do
    for vehicle <- @vehicles, n <- [-5.0, 5.0], e <- [-5.0, 5.0], d <- [-5.0, 5.0] do
      sim = run(vehicle, {n, e, d}, 1000.0, {1.0, -1.0, 1.0}, [])
      assert finite?(sim.dyn), "#{vehicle} in {#{n}, #{e}, #{d}}: #{inspect(sim.dyn)}"
    end
  end

  test "ordinary conditions take one step; a long tether in a strong current takes more" do
    params = Dynamics.params(:neptunus)
    assert Dynamics.substeps(%State{}, {0.0, 0.0, 0.0}, 0.01, params) == 1
    assert Dynamics.substeps(%State{u: 1.0, r: 0.5}, {0.3, 0.2, 0.0}, 0.01, params) == 1

    long = Neptunus.Test.Vehicles.variant(&put_in(&1, ["tether", "length"], 1000.0))
    n = Dynamics.substeps(%State{}, {5.0, -5.0, 5.0}, 0.01, long)
    assert n > 1 and n < 1000
    # twice the step: at least as many sub-steps
    assert Dynamics.substeps(%State{}, {5.0, -5.0, 5.0}, 0.02, long) >= n
  end
end
