defmodule Neptunus.Navigation.PositionFilterTest do
  use ExUnit.Case, async: true

  import Neptunus.Test.Properties

  alias Neptunus.Navigation.Matrix, as: M
  alias Neptunus.Navigation.PositionFilter, as: F

  doctest Neptunus.Navigation.Matrix

  defp started(t \\ 0.0), do: F.new() |> F.start(t, {{0.0, 0.0}, 1.0}, {{0.0, 0.0}, 0.25})

  defp vel(t, vx, vy, psi \\ 0.0, sigma \\ 0.01),
    do: %{
      t: t,
      kind: :velocity,
      z: [vx, vy],
      r: M.diag([sigma * sigma, sigma * sigma]),
      psi: psi,
      psi_var: 1.0e-4
    }

  defp fix(t, n, e, sigma \\ 0.3),
    do: %{t: t, kind: :position, z: [n, e], r: M.diag([sigma * sigma, sigma * sigma])}

  defp feed(f, measurements) do
    Enum.reduce(measurements, f, fn m, f ->
      {:accepted, _, f} = F.insert(f, m, gate: 100.0)
      f
    end)
  end

  test "a velocity in the vehicle frame is turned by the heading into north and east" do
    f = feed(started(), for(k <- 1..20, do: vel(k * 0.1, 0.5, 0.0, :math.pi() / 2)))
    {[_, _, vn, ve], _} = F.at(f, 2.0)
    assert_in_delta vn, 0.0, 0.01
    assert_in_delta ve, 0.5, 0.01
  end

  test "a fix delayed past later velocities gives what it would have given on time" do
    velocities = for k <- 1..30, do: vel(k * 0.1, 0.3, 0.05, 0.3)
    late_fix = fix(1.55, 0.4, 0.1)

    in_order =
      (velocities ++ [late_fix])
      |> Enum.sort_by(& &1.t)
      |> then(&feed(started(), &1))

    delayed = started() |> feed(velocities) |> feed([late_fix])

    {xa, pa} = F.at(in_order, 3.0)
    {xb, pb} = F.at(delayed, 3.0)
    for {a, b} <- Enum.zip(xa, xb), do: assert_in_delta(a, b, 1.0e-9)

    for {ra, rb} <- Enum.zip(pa, pb),
        {a, b} <- Enum.zip(ra, rb),
        do: assert_in_delta(a, b, 1.0e-12)
  end

  test "a delayed fix is gated against the state at its own time" do
    # the vehicle moved 3 m north since the fix was taken: on time the fix agrees
    start = F.new() |> F.start(0.0, {{0.0, 0.0}, 0.01}, {{1.0, 0.0}, 0.01})
    f = feed(start, for(k <- 1..30, do: vel(k * 0.1, 1.0, 0.0)))
    assert {:accepted, %{d2: d2}, _} = F.insert(f, fix(0.5, 0.5, 0.0, 0.3), gate: 4.0)
    assert d2 < 4.0
    # judged against the newest state it would have been 2.5 m off
    assert {:rejected, :innovation, %{y: [dn, _]}, ^f} =
             F.insert(f, fix(0.5, -2.0, 0.0, 0.3), gate: 4.0)

    assert dn < -2.0
  end

  test "older than the window: refused, the filter unchanged" do
    f = feed(started(), for(k <- 1..60, do: vel(k * 0.1, 0.1, 0.0)))
    assert {:rejected, :too_old, nil, ^f} = F.insert(f, fix(1.0, 0.0, 0.0))
    assert {:accepted, _, _} = F.insert(f, fix(3.5, 0.35, 0.0))
  end

  test "a filter that has not started refuses measurements" do
    assert {:rejected, :not_started, nil, _} = F.insert(F.new(), fix(1.0, 0.0, 0.0))
  end

  test "the absolute gate floor keeps a very sure filter from rejecting good readings" do
    f = feed(started(), for(k <- 1..100, do: fix(k * 0.1, 0.0, 0.0, 0.01)))
    assert {:rejected, :innovation, _, _} = F.insert(f, fix(10.1, 0.3, 0.0, 0.01), gate: 4.0)
    assert {:accepted, _, _} = F.insert(f, fix(10.1, 0.3, 0.0, 0.01), gate: 4.0, min_gate: 0.5)
  end

  test "reset_position re-acquires at a past time and keeps the later motion" do
    f = feed(started(), for(k <- 1..20, do: vel(k * 0.1, 1.0, 0.0)))
    f = F.reset_position(f, 1.0, {[10.0, 5.0], M.diag([0.1, 0.1])})
    {[n, e, vn, _], p} = F.at(f, 2.0)
    assert_in_delta n, 11.0, 0.05
    assert_in_delta e, 5.0, 0.01
    assert_in_delta vn, 1.0, 0.01
    assert M.at(p, 0, 0) < 0.2
  end

  test "property: the covariance stays symmetric and positive whatever arrives, in any order" do
    m =
      :proper_types.oneof([
        :proper_types.tuple([
          :proper_types.exactly(:v),
          :proper_types.float(0.0, 5.0),
          :proper_types.float(-2.0, 2.0),
          :proper_types.float(-2.0, 2.0),
          :proper_types.float(-4.0, 4.0)
        ]),
        :proper_types.tuple([
          :proper_types.exactly(:f),
          :proper_types.float(0.0, 5.0),
          :proper_types.float(-20.0, 20.0),
          :proper_types.float(-20.0, 20.0),
          :proper_types.float(0.05, 5.0)
        ])
      ])

    check(
      :proper_types.list(m),
      fn list ->
        f =
          Enum.reduce(list, started(), fn
            {:v, t, vx, vy, psi}, f -> elem3(F.insert(f, vel(t, vx, vy, psi), gate: 4.0))
            {:f, t, n, e, s}, f -> elem3(F.insert(f, fix(t, n, e, s), gate: 4.0))
          end)

        {_, p} = F.at(f, 6.0)

        symmetric =
          Enum.all?(for i <- 0..3, j <- 0..3, do: abs(M.at(p, i, j) - M.at(p, j, i)) < 1.0e-9)

        diagonal = Enum.all?(for i <- 0..3, do: M.at(p, i, i) > 0)
        {a, b, _} = M.ellipse(M.block(p, 0, 1))
        symmetric and diagonal and a >= b and b >= 0
      end,
      300
    )
  end

  defp elem3({:accepted, _, f}), do: f
  defp elem3({:rejected, _, _, f}), do: f

  test "the 1-σ ellipse of a covariance: semi-axes and direction" do
    {a, b, angle} = M.ellipse([[4.0, 0.0], [0.0, 1.0]])
    assert {a, b, angle} == {2.0, 1.0, 0.0}
    {a, b, angle} = M.ellipse([[1.0, 0.0], [0.0, 9.0]])
    assert {a, b} == {3.0, 1.0}
    assert_in_delta abs(angle), :math.pi() / 2, 1.0e-12
    {_, _, angle} = M.ellipse([[2.0, 1.0], [1.0, 2.0]])
    assert_in_delta angle, :math.pi() / 4, 1.0e-12
  end
end
