defmodule Neptunus.GCS.SchedulerTest do
  use ExUnit.Case, async: true
  doctest Neptunus.GCS.Scheduler

  import Neptunus.Test.Properties

  alias Neptunus.GCS.Scheduler

  # ticks every ~50 ms with the jitter BEAM timers have (up to 15 ms late, a few early)
  defp run(s, sysid, names, ticks) do
    Enum.reduce(ticks, {s, []}, fn now, {s, sent} ->
      {s, due} = Scheduler.due(s, sysid, names, now)
      {s, sent ++ Enum.map(due, &{&1, now})}
    end)
  end

  defp times(sent, name), do: for({^name, t} <- sent, do: t)

  test "each message at its interval, ticks jittering: ATTITUDE 10 Hz, SYS_STATUS 2 Hz, HEARTBEAT 1 Hz" do
    ticks = for i <- 0..199, do: i * 50 + rem(i * 7, 13) - 3
    {_s, sent} = run(Scheduler.new(), 1, [:attitude, :sys_status, :heartbeat], ticks)

    assert length(times(sent, :attitude)) in 98..101
    assert length(times(sent, :sys_status)) in 19..21
    assert length(times(sent, :heartbeat)) in 10..11

    gaps =
      sent
      |> times(:attitude)
      |> Enum.chunk_every(2, 1, :discard)
      |> Enum.map(fn [a, b] -> b - a end)

    assert Enum.all?(gaps, &(&1 in 80..130)), inspect(gaps)
  end

  test "SET_MESSAGE_INTERVAL: faster, slower, off, back to the default; per vehicle" do
    {:ok, s} = Scheduler.set_interval(Scheduler.new(), 1, 30, 50_000)
    {:ok, s} = Scheduler.set_interval(s, 1, 74, -1)
    {:ok, s} = Scheduler.set_interval(s, 1, 0, 10_000)
    ticks = for i <- 0..19, do: i * 50

    {_s, sent} = run(s, 1, [:attitude, :vfr_hud, :heartbeat], ticks)
    assert length(times(sent, :attitude)) == 20
    assert times(sent, :vfr_hud) == []
    # at least the tick
    assert length(times(sent, :heartbeat)) == 20

    # vehicle 2 keeps the defaults
    {_s, sent} = run(s, 2, [:vfr_hud], ticks)
    assert length(times(sent, :vfr_hud)) == 10

    {:ok, s} = Scheduler.set_interval(s, 1, 74, 0)
    assert Scheduler.interval_us(s, 1, 74) == 100_000
    {:ok, s} = Scheduler.set_interval(s, 1, 74, 3_600_000_000)
    assert Scheduler.interval_us(s, 1, 74) == 60_000_000
    assert {:error, _} = Scheduler.interval_us(s, 1, 9999)
  end

  test "REQUEST_DATA_STREAM: a stream at a rate, all of them, stopped, restored" do
    s = Scheduler.data_stream(Scheduler.new(), 1, 10, 4, true)
    assert Scheduler.interval_us(s, 1, 30) == 250_000
    s = Scheduler.data_stream(s, 1, 0, 1, true)
    assert Scheduler.interval_us(s, 1, 74) == 1_000_000
    s = Scheduler.data_stream(s, 1, 0, 0, false)
    assert Scheduler.interval_us(s, 1, 1) == -1
    s = Scheduler.data_stream(s, 1, 0, 0, true)
    assert Scheduler.interval_us(s, 1, 1) == 500_000
  end

  test "messages the vehicle does not have at a tick wait for one that has them" do
    {s, []} = Scheduler.due(Scheduler.new(), 1, [], 0)
    assert {_s, [:attitude]} = Scheduler.due(s, 1, [:attitude], 10)
  end

  test "a message keeps its rhythm: never ahead of it (but for the early allowance), whatever the ticks" do
    check(
      {:proper_types.list(:proper_types.integer(0, 200)), :proper_types.integer(50, 2_000)},
      fn {steps, interval_ms} ->
        {:ok, s} = Scheduler.set_interval(Scheduler.new(), 1, 30, interval_ms * 1000)
        ticks = Enum.scan(steps, 0, &(&1 + &2))
        {_s, sent} = run(s, 1, [:attitude], ticks)

        case times(sent, :attitude) do
          [] ->
            true

          [first | _] = times ->
            times
            |> Enum.with_index()
            |> Enum.all?(fn {t, k} -> t - first >= k * interval_ms - 20 end)
        end
      end
    )
  end
end
