defmodule Neptunus.Vehicle.Board.OpenROV.PacerTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.Vehicle.Board.OpenROV
  alias Neptunus.Vehicle.Board.OpenROV.Pacer

  doctest Pacer

  # Runs a schedule of pushes [{at_ms, key, bytes}] through the pacer, taking at every
  # millisecond, and returns the writes [{at, key, bytes}] in order.
  defp run(pushes, until) do
    by_time = Enum.group_by(pushes, &elem(&1, 0))

    {writes, _p} =
      Enum.reduce(0..until, {[], Pacer.new()}, fn now, {writes, p} ->
        p =
          Enum.reduce(Map.get(by_time, now, []), p, fn
            {_, key, bytes}, p ->
              {:ok, p} = Pacer.push(p, key, bytes)
              p

            {_, key, bytes, sticky}, p ->
              {:ok, p} = Pacer.push(p, key, bytes, sticky: sticky)
              p
          end)

        {out, p} = Pacer.take(p, now)
        {writes ++ Enum.map(out, fn {key, bytes} -> {now, key, bytes} end), p}
      end)

    writes
  end

  defp window_ok?(writes) do
    Enum.all?(writes, fn {t0, _, _} ->
      writes
      |> Enum.filter(fn {t, _, _} -> t >= t0 and t - t0 < 30 end)
      |> Enum.map(fn {_, _, b} -> byte_size(b) end)
      |> Enum.sum()
      |> Kernel.<=(60)
    end)
  end

  defp spaced?(writes) do
    writes
    |> Enum.map(&elem(&1, 0))
    |> Enum.chunk_every(2, 1, :discard)
    |> Enum.all?(fn [a, b] -> b - a >= 3 end)
  end

  test "a burst (lights + tilt + go + ping, framed for 30.x) never puts more than 60 bytes in any 30 ms and spaces commands ≥ 3 ms" do
    burst =
      [
        {{:device, :lights}, OpenROV.Protocol.lights(255)},
        {{:device, :tilt}, OpenROV.Protocol.tilt(1750)},
        {:go, OpenROV.Protocol.go({2000, 1500, 2000}, true)},
        {:ping, OpenROV.Protocol.ping(123_456)},
        {:mtrmod1, OpenROV.Protocol.mtrmod1({100, 100, 100})},
        {:mtrmod2, OpenROV.Protocol.mtrmod2({100, 100, 100})},
        {{:device, :laser}, OpenROV.Protocol.laser(255)}
      ]
      |> Enum.map(fn {k, b} -> {0, k, OpenROV.Protocol.frame(b, :openrov_30)} end)

    writes = run(burst, 500)
    assert length(writes) == 7
    assert window_ok?(writes)
    assert spaced?(writes)
    # written in the order queued
    assert Enum.map(writes, &elem(&1, 1)) == Enum.map(burst, &elem(&1, 1))
  end

  test "the newest go() replaces a queued go() in its place; devices coalesce per device" do
    pushes = [
      {0, {:device, :lights}, "ligt(1);"},
      {0, :go, "go(1600,1500,1500,1);"},
      {0, {:device, :lights}, "ligt(2);"},
      {1, :go, "go(1700,1500,1500,1);"},
      {1, :go, "go(1500,1500,1500,1);"}
    ]

    assert [{0, _, "ligt(2);"}, {3, :go, "go(1500,1500,1500,1);"}] = run(pushes, 100)
  end

  test "a queued neutral (sticky) go() is never replaced: a newer go() waits behind it" do
    pushes = [
      {0, :ping, "ping(1);"},
      {1, :go, "go(1500,1500,1500,1);", true},
      {1, :go, "go(1700,1500,1500,1);", false},
      {2, :go, "go(1800,1500,1500,1);", false}
    ]

    assert Enum.map(run(pushes, 100), &elem(&1, 2)) ==
             ["ping(1);", "go(1500,1500,1500,1);", "go(1800,1500,1500,1);"]

    # a newer neutral supersedes everything queued under go
    pushes = [
      {0, :ping, "ping(1);"},
      {1, :go, "go(1500,1500,1500,1);", true},
      {1, :go, "go(1700,1500,1500,1);", false},
      {2, :go, "go(1500,1500,1500,0);", true}
    ]

    assert Enum.map(run(pushes, 100), &elem(&1, 2)) == ["ping(1);", "go(1500,1500,1500,0);"]
  end

  test "a command alone goes out at once; next_at says when a queued one may go, nil when idle" do
    p = Pacer.new()
    assert Pacer.next_at(p, 0) == nil
    {:ok, p} = Pacer.push(p, :go, "go(1500,1500,1500,1);")
    assert {[{:go, _}], p} = Pacer.take(p, 100)
    {:ok, p} = Pacer.push(p, :ping, "ping(1);")
    assert Pacer.take(p, 101) == {[], p}
    assert Pacer.next_at(p, 101) == 103
    assert {[{:ping, "ping(1);"}], p} = Pacer.take(p, 103)
    assert Pacer.next_at(p, 103) == nil
  end

  test "next_at waits for the window: 3 × 22 bytes need the first to leave the window" do
    go = "go(1500,1500,1500,1);"
    p = Pacer.new()
    {:ok, p} = Pacer.push(p, :a, go)
    {[_], p} = Pacer.take(p, 0)
    {:ok, p} = Pacer.push(p, :b, go)
    {[_], p} = Pacer.take(p, 3)
    {:ok, p} = Pacer.push(p, :c, go)
    assert Pacer.take(p, 6) == {[], p}
    assert Pacer.next_at(p, 6) == 30
    assert {[{:c, ^go}], _} = Pacer.take(p, 30)
  end

  test "a command that could never be sent is refused and changes nothing" do
    p = Pacer.new()
    assert {:error, _} = Pacer.push(p, :x, String.duplicate("a", 61))
    assert {:error, _} = Pacer.push(p, :x, "")
    assert Pacer.queued(p) == 0
  end

  test "property: any schedule of pushes is written within the limits, the newest of each key last" do
    gen =
      :proper_types.list(
        {:proper_types.integer(0, 200), :proper_types.elements([:go, :ping, :l, :t, :m]),
         :proper_types.integer(1, 30), :proper_types.bool()}
      )

    check(
      gen,
      fn pushes ->
        pushes =
          pushes
          |> Enum.with_index()
          |> Enum.map(fn {{t, k, n, sticky}, i} ->
            {t, k, String.duplicate("x", n) <> "#{i}", sticky}
          end)

        writes = run(pushes, 1_200)
        written = MapSet.new(writes, &elem(&1, 2))

        # every sticky command is written unless a later sticky one of its key superseded it
        in_order = Enum.sort_by(Enum.with_index(pushes), fn {{t, _, _, _}, i} -> {t, i} end)

        stickies_kept =
          in_order
          |> Enum.with_index()
          |> Enum.all?(fn {{{_, k, b, sticky}, _}, pos} ->
            not sticky or MapSet.member?(written, b) or
              Enum.any?(Enum.drop(in_order, pos + 1), fn {{_, k2, _, s2}, _} ->
                k2 == k and s2
              end)
          end)

        last_pushed =
          pushes
          |> Enum.sort_by(&elem(&1, 0))
          |> Enum.reduce(%{}, fn {_, k, b, _}, acc -> Map.put(acc, k, b) end)

        last_written = Enum.reduce(writes, %{}, fn {_, k, b}, acc -> Map.put(acc, k, b) end)

        window_ok?(writes) and spaced?(writes) and last_written == last_pushed and stickies_kept
      end,
      200
    )
  end
end
