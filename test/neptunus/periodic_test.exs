defmodule Neptunus.PeriodicTest do
  use ExUnit.Case, async: true
  doctest Neptunus.Periodic

  alias Neptunus.Periodic

  test "new/2 sets the first deadline one period ahead" do
    p = Periodic.new(100, 0)
    assert p.period == div(System.convert_time_unit(1, :second, :native), 100)
    assert p.next == p.period
  end

  test "deadlines stay on the ideal grid however late the ticks come" do
    p = %Periodic{period: 10, next: 10}

    {_, p} =
      Enum.reduce([12, 25, 31, 79, 80, 95], {0, p}, fn now, {_, p} ->
        {due, p} = Periodic.advance(p, now)
        assert due >= 1
        assert p.next > now
        assert rem(p.next, 10) == 0
        {due, p}
      end)

    assert p.next == 100
  end

  test "each deadline is counted exactly once, early ticks consume the next one" do
    p = %Periodic{period: 7, next: 7}
    # 7: on time (1); 30: deadlines 14, 21, 28 (3); 31: early for 35, takes it (1); 70: 42..70 (5)
    {dues, p} = Enum.map_reduce([7, 30, 31, 70], p, &Periodic.advance(&2, &1))
    assert dues == [1, 3, 1, 5]
    assert Enum.sum(dues) == div(70, 7)
    assert p.next == 77
  end

  test "arm/2 delivers the message at the deadline" do
    p = Periodic.new(200)
    Periodic.arm(p, :tick)
    assert_receive :tick
  end
end
