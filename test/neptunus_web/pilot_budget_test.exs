defmodule NeptunusWeb.PilotBudgetTest do
  use ExUnit.Case, async: true

  alias NeptunusWeb.PilotBudget

  doctest NeptunusWeb.PilotBudget

  defp run(budget, times), do: Enum.map_reduce(times, budget, &PilotBudget.frame(&2, &1))

  test "up to the limit within one second, over after, fresh in the next second" do
    {verdicts, budget} = run(PilotBudget.new(3), [100, 200, 300, 400, 1_099])
    assert verdicts == [:within, :within, :within, :over, :over]
    {verdicts, _} = run(budget, [1_100, 1_101, 1_102, 1_103])
    assert verdicts == [:within, :within, :within, :over]
  end

  test "a steady client at the limit always stays within" do
    {verdicts, _} = run(PilotBudget.new(50), Enum.map(0..499, &(&1 * 20)))
    assert Enum.all?(verdicts, &(&1 == :within))
  end

  test "a clock that goes back starts a new window instead of counting on" do
    {verdicts, _} = run(PilotBudget.new(1), [5_000, 5_001, 10, 11])
    assert verdicts == [:within, :over, :within, :over]
  end

  test "the limit must be a positive integer" do
    assert_raise FunctionClauseError, fn -> PilotBudget.new(0) end
    assert_raise FunctionClauseError, fn -> PilotBudget.new(1.5) end
  end
end
