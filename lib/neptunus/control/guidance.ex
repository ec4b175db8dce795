defmodule Neptunus.Control.Guidance do
  @moduledoc """
  Line-of-sight path following between two waypoints (Fossen, *Handbook of Marine Craft
  Hydrodynamics and Motion Control*, 2011, §10.3: lookahead-based steering). Pure.

  The path from `p_k` to `p_k+1` has the direction `α = atan2(Δe, Δn)`. The vehicle at `p`
  is `s` along it and `y_e` across it (positive to starboard of the path):

      s   =  (n − n_k) cos α + (e − e_k) sin α
      y_e = −(n − n_k) sin α + (e − e_k) cos α

  and is steered towards the point `Δ` (the *lookahead distance*) ahead of its projection
  on the path, which gives the desired course

      χ_d = α − atan(y_e / Δ)

  — a proportional steering law with gain `1/Δ` that turns through at most 90° however far
  off the path the vehicle is. A short `Δ` converges quickly and overshoots; a long one is
  gentle. Fossen recommends `Δ` of about two vehicle lengths or more; the default here is
  `max(#{1.5} m, 2 · acceptance radius)`.

  **Course, not heading.** A current or a tether pulls the vehicle sideways, so its course
  over the ground differs from its heading by the crab angle `β`. `heading/3` turns the
  desired course into the heading to hold, `ψ_d = χ_d − β`, with `β` from the estimated
  velocity over the ground (a DVL measures it), kept within ±30° and only when the vehicle
  moves at least 5 cm/s (below that `β` is noise).
  """

  @min_lookahead 1.5
  @max_crab 0.52
  @crab_speed 0.05

  @typedoc """
  * `alpha` — the path's direction (rad); `along` — `s` (m) along it from its start;
    `cross_track` — `y_e` (m, positive to starboard of the path); `course` — `χ_d` (rad,
    `[0, 2π)`); `length` — the path's length; `remaining` — along the path to its end (m)
  """
  @type t :: %{
          alpha: float(),
          along: float(),
          cross_track: float(),
          course: float(),
          length: float(),
          remaining: float()
        }

  @doc "The default lookahead distance for an acceptance radius (m)."
  @spec lookahead(number()) :: float()
  def lookahead(radius), do: max(@min_lookahead, 2.0 * radius) * 1.0

  @doc """
  Line of sight at `p` `{n, e}` on the path from `from` to `to` (`{n, e}`, distinct) with
  lookahead `delta` (m, > 0).

      iex> g = Neptunus.Control.Guidance.los({0.0, 1.0}, {0.0, 0.0}, {10.0, 0.0}, 1.0)
      iex> {g.cross_track, Float.round(g.course, 6), g.remaining}
      {1.0, Float.round(2 * :math.pi() - :math.pi() / 4, 6), 10.0}
  """
  @spec los({number(), number()}, {number(), number()}, {number(), number()}, number()) :: t()
  def los({n, e}, {nk, ek}, {n1, e1}, delta) when delta > 0 do
    {dn, de} = {n1 - nk, e1 - ek}
    length = :math.sqrt(dn * dn + de * de)
    alpha = :math.atan2(de, dn)
    {c, s} = {:math.cos(alpha), :math.sin(alpha)}
    along = (n - nk) * c + (e - ek) * s
    cross = -(n - nk) * s + (e - ek) * c
    course = wrap_2pi(alpha - :math.atan(cross / delta))

    %{
      alpha: wrap_2pi(alpha),
      along: along,
      cross_track: cross,
      course: course,
      length: length,
      remaining: length - along
    }
  end

  @doc """
  The heading to hold for the desired `course` (rad) given the vehicle's `heading` (rad) and
  its estimated velocity over the ground `{vₙ, vₑ}` (m/s, or nil): `χ_d − β` (see the
  moduledoc).

      iex> # a current from the west sets the vehicle 0.1 rad to the east of its heading
      iex> psi = Neptunus.Control.Guidance.heading(0.0, 0.0, {0.5 * :math.cos(0.1), 0.5 * :math.sin(0.1)})
      iex> Float.round(psi - 2 * :math.pi(), 6)
      -0.1
  """
  @spec heading(number(), number(), {number(), number()} | nil) :: float()
  def heading(course, _heading, nil), do: wrap_2pi(course)

  def heading(course, heading, {vn, ve}) do
    speed = :math.sqrt(vn * vn + ve * ve)

    if speed < @crab_speed do
      wrap_2pi(course)
    else
      crab = wrap_pi(:math.atan2(ve, vn) - heading) |> max(-@max_crab) |> min(@max_crab)
      wrap_2pi(course - crab)
    end
  end

  @doc "An angle wrapped to `[0, 2π)`."
  @spec wrap_2pi(number()) :: float()
  def wrap_2pi(a), do: Neptunus.Dynamics.wrap_2pi(a * 1.0)

  @doc "An angle wrapped to `[−π, π)`."
  @spec wrap_pi(number()) :: float()
  def wrap_pi(a), do: Neptunus.Dynamics.wrap_pi(a * 1.0)
end
