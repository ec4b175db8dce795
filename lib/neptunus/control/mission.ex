defmodule Neptunus.Control.Mission do
  @moduledoc """
  A mission: waypoints followed one leg after another with line-of-sight guidance
  (`Neptunus.Control.Guidance`). Pure; `Neptunus.Control.DP` runs it in control mode `dp`.

  ## Waypoints

  Each waypoint has `north`, `east` (m, in the position's frame), `depth` (m), an optional
  `heading` (rad: the heading to hold on the way to it and once there, where the vehicle can;
  nil lets the guidance choose), `speed` (m/s, 0.05..1, default #{0.3}) and an acceptance
  `radius` (m, 0.2..20, default #{0.5}). `validate/2` checks an untrusted payload (a list of
  waypoints, or a survey `Neptunus.Control.Survey` generates them from) and refuses, with a
  reason, a mission that is malformed or cannot be flown from where the vehicle is: more than
  #{100} waypoints, a waypoint beyond `max_range` (default #{200} m) of the vehicle, deeper
  than `max_depth` (default #{100} m), or two consecutive waypoints at the same place.

  ## Running

  The first leg runs from where the vehicle is when the mission starts to waypoint 1; each
  later one from the previous waypoint to the next. A waypoint is reached when the vehicle
  is within its radius, or has passed the end of the leg (`along ≥ length`: a vehicle
  pushed off the line does not circle back for a point it went by). Then the next leg
  begins; after the last waypoint the mission is `:done` and the vehicle holds position
  there. On a leg the guidance gives the course to steer (LOS, lookahead
  `Guidance.lookahead/1` of the target's radius), the speed (the waypoint's, slowing down
  over the last metres to the final waypoint so it stops there), the depth (the target
  waypoint's) and the heading (the waypoint's, or nil).

  **Pause** holds position where the vehicle is; **resume** goes on with the same leg (the
  guidance brings the vehicle back onto the line). Aborting is the caller's: it drops the
  mission and holds position (`Neptunus.Control.DP`).
  """

  alias Neptunus.Control.{Guidance, Survey}
  alias Neptunus.Validate, as: V

  @max_waypoints 100
  @max_range 200.0
  @max_depth 100.0
  @default_speed 0.3
  @default_radius 0.5
  @slowdown 0.4

  @typedoc "A waypoint (SI; `heading` rad or nil)."
  @type waypoint :: %{
          north: float(),
          east: float(),
          depth: float(),
          heading: float() | nil,
          speed: float(),
          radius: float()
        }

  @enforce_keys [:id, :waypoints, :from]
  defstruct [:id, :waypoints, :from, :guidance, leg: 0, state: :running]

  @typedoc """
  * `id` — the mission's number (a new one for each start or change)
  * `waypoints` — in order; `leg` — the index of the waypoint being steered to
  * `from` — `{n, e}` where the current leg starts
  * `state` — `:running`, `:paused` or `:done`
  * `guidance` — the last step's `Guidance.los/4` with the speed, depth and heading, or nil
  """
  @type t :: %__MODULE__{
          id: non_neg_integer(),
          waypoints: [waypoint()],
          from: {float(), float()},
          leg: non_neg_integer(),
          state: :running | :paused | :done,
          guidance: map() | nil
        }

  @doc "The most waypoints a mission may have."
  @spec max_waypoints() :: pos_integer()
  def max_waypoints, do: @max_waypoints

  @doc """
  Checks an untrusted mission payload — `%{"waypoints" => [...]}` or `%{"survey" => {...}}`
  (`north`, `east`, `heading` rad, `length`, `width`, `spacing`, `depth`, optional `speed`,
  `radius`) — against the vehicle's position `{n, e}` (m). Options `max_range`, `max_depth`.
  Returns the waypoints or a reason a pilot can read.

      iex> Neptunus.Control.Mission.validate(%{"waypoints" => []}, {0.0, 0.0})
      {:error, "a mission needs at least one waypoint"}

      iex> Neptunus.Control.Mission.validate(
      ...>   %{"waypoints" => [%{"north" => 500, "east" => 0, "depth" => 2}]}, {0.0, 0.0})
      {:error, "waypoint 1 is 500.0 m away: beyond the 200 m a mission may reach"}
  """
  @spec validate(term(), {float(), float()}, keyword()) ::
          {:ok, [waypoint()]} | {:error, String.t()}
  def validate(payload, position, opts \\ []) do
    with {:ok, waypoints} <- parse(payload) do
      reachable(waypoints, position, opts)
    end
  end

  def parse(%{"waypoints" => list} = map) when is_list(list) do
    with :ok <- V.object(map, "", ["waypoints"]),
         :ok <- count(length(list)) do
      list
      |> Enum.with_index()
      |> V.map_ok(fn {wp, i}, _ -> waypoint(wp, "waypoints[#{i}]") end)
    end
  end

  def parse(%{"waypoints" => other}),
    do: {:error, "waypoints must be a list, got #{V.show(other)}"}

  def parse(%{"survey" => survey} = map) do
    with :ok <- V.object(map, "", ["survey"]),
         {:ok, survey} <- survey(survey, "survey") do
      {:ok, Survey.waypoints(survey)}
    end
  end

  def parse(map) when is_map(map),
    do: {:error, "a mission needs waypoints (a list) or a survey (an object)"}

  def parse(other), do: {:error, "a mission must be an object, got #{V.show(other)}"}

  defp count(0), do: {:error, "a mission needs at least one waypoint"}

  defp count(n) when n > @max_waypoints,
    do: {:error, "a mission has at most #{@max_waypoints} waypoints, got #{n}"}

  defp count(_n), do: :ok

  defp waypoint(wp, path) do
    with :ok <- V.object(wp, path, ~w(north east depth), ~w(heading speed radius)),
         {:ok, n} <- V.required(wp, path, "north", &coordinate/2),
         {:ok, e} <- V.required(wp, path, "east", &coordinate/2),
         {:ok, depth} <- V.required(wp, path, "depth", &V.number(&1, &2, min: 0, max: 200)),
         {:ok, heading} <- V.optional(wp, path, "heading", nil, &heading/2),
         {:ok, speed} <- V.optional(wp, path, "speed", @default_speed, &speed/2),
         {:ok, radius} <- V.optional(wp, path, "radius", @default_radius, &radius/2) do
      {:ok,
       %{
         north: n * 1.0,
         east: e * 1.0,
         depth: depth * 1.0,
         heading: heading && Guidance.wrap_2pi(heading),
         speed: speed * 1.0,
         radius: radius * 1.0
       }}
    end
  end

  defp survey(map, path) do
    required = ~w(north east heading length width spacing depth)

    with :ok <- V.object(map, path, required, ~w(speed radius)),
         {:ok, n} <- V.required(map, path, "north", &coordinate/2),
         {:ok, e} <- V.required(map, path, "east", &coordinate/2),
         {:ok, heading} <- V.required(map, path, "heading", &heading/2),
         {:ok, length} <- V.required(map, path, "length", &V.number(&1, &2, min: 1, max: 1000)),
         {:ok, width} <- V.required(map, path, "width", &V.number(&1, &2, min: 0, max: 1000)),
         {:ok, spacing} <-
           V.required(map, path, "spacing", &V.number(&1, &2, min: 0.5, max: 100)),
         {:ok, depth} <- V.required(map, path, "depth", &V.number(&1, &2, min: 0, max: 200)),
         {:ok, speed} <- V.optional(map, path, "speed", @default_speed, &speed/2),
         {:ok, radius} <- V.optional(map, path, "radius", @default_radius, &radius/2),
         :ok <- survey_count(width, spacing) do
      {:ok,
       %{
         origin: {n * 1.0, e * 1.0},
         heading: heading * 1.0,
         length: length * 1.0,
         width: width * 1.0,
         spacing: spacing * 1.0,
         depth: depth * 1.0,
         speed: speed * 1.0,
         radius: radius * 1.0
       }}
    end
  end

  defp survey_count(width, spacing) do
    n = Survey.count(width, spacing)

    if n > @max_waypoints,
      do:
        {:error,
         "the survey makes #{n} waypoints, at most #{@max_waypoints}: widen the spacing or narrow the area"},
      else: :ok
  end

  defp coordinate(value, path), do: V.number(value, path, min: -10_000, max: 10_000)

  defp heading(nil, _path), do: {:ok, nil}

  defp heading(value, path) do
    case V.number(value, path, min: -2 * :math.pi(), max: 2 * :math.pi()) do
      {:ok, x} ->
        {:ok, x}

      {:error, _} ->
        {:error,
         "#{path} must be a heading in [-6.2832, 6.2832] rad or null, got #{V.show(value)}"}
    end
  end

  defp speed(value, path), do: V.number(value, path, min: 0.05, max: 1)
  defp radius(value, path), do: V.number(value, path, min: 0.2, max: 20)

  @doc """
  Whether validated `waypoints` can be flown from `{n, e}` (see the moduledoc): the
  waypoints, or why not. Options `max_range`, `max_depth`.
  """
  @spec reachable([waypoint()], {float(), float()}, keyword()) ::
          {:ok, [waypoint()]} | {:error, String.t()}
  def reachable(waypoints, {n0, e0}, opts \\ []) do
    max_range = Keyword.get(opts, :max_range, @max_range)
    max_depth = Keyword.get(opts, :max_depth, @max_depth)

    waypoints
    |> Enum.with_index(1)
    |> Enum.reduce_while(nil, fn {wp, i}, previous ->
      range = :math.sqrt((wp.north - n0) ** 2 + (wp.east - e0) ** 2)

      cond do
        range > max_range ->
          {:halt,
           {:error,
            "waypoint #{i} is #{fmt(range)} m away: beyond the #{fmt_int(max_range)} m a mission may reach"}}

        wp.depth > max_depth ->
          {:halt,
           {:error,
            "waypoint #{i} is #{fmt(wp.depth)} m deep: beyond this vehicle's #{fmt_int(max_depth)} m"}}

        previous != nil and same_place?(previous, wp) ->
          {:halt, {:error, "waypoints #{i - 1} and #{i} are the same point"}}

        true ->
          {:cont, wp}
      end
    end)
    |> case do
      {:error, _} = error -> error
      _ -> {:ok, waypoints}
    end
  end

  defp same_place?(a, b),
    do:
      :math.sqrt((a.north - b.north) ** 2 + (a.east - b.east) ** 2) < 0.1 and
        abs(a.depth - b.depth) < 0.1

  @doc "A mission `id` over `waypoints` (validated), starting where the vehicle is (`{n, e}`)."
  @spec start(non_neg_integer(), [waypoint()], {float(), float()}) :: t()
  def start(id, waypoints, {n, e}),
    do: %__MODULE__{id: id, waypoints: waypoints, from: {n * 1.0, e * 1.0}}

  @doc "Pauses a running mission (the caller holds position)."
  @spec pause(t()) :: {:ok, t()} | {:error, String.t()}
  def pause(%__MODULE__{state: :running} = m), do: {:ok, %{m | state: :paused}}
  def pause(%__MODULE__{state: state}), do: {:error, "the mission is #{state}: nothing to pause"}

  @doc "Resumes a paused mission on the same leg."
  @spec resume(t()) :: {:ok, t()} | {:error, String.t()}
  def resume(%__MODULE__{state: :paused} = m), do: {:ok, %{m | state: :running}}

  def resume(%__MODULE__{state: state}),
    do: {:error, "the mission is #{state}: nothing to resume"}

  @doc "Moves every waypoint and the leg's start by `{dn, de}` (a change of the position's frame)."
  @spec shift(t(), {number(), number()}) :: t()
  def shift(%__MODULE__{} = m, {dn, de}) do
    {fn_, fe} = m.from

    %{
      m
      | from: {fn_ + dn, fe + de},
        waypoints: Enum.map(m.waypoints, &%{&1 | north: &1.north + dn, east: &1.east + de})
    }
  end

  @doc "The waypoint being steered to (the last one once done)."
  @spec target(t()) :: waypoint()
  def target(%__MODULE__{} = m), do: Enum.at(m.waypoints, min(m.leg, length(m.waypoints) - 1))

  @doc """
  One step of a running mission at position `{n, e}`: advances the leg when its waypoint is
  reached and returns the mission with its `guidance` — `%{course, speed, depth, heading,
  cross_track, along, length, remaining, distance, alpha}` — and the events `{:reached, i}`
  (1-based) and `:done`. A paused or done mission does not move.
  """
  @spec step(t(), {float(), float()}) :: {t(), [{:reached, pos_integer()} | :done]}
  def step(%__MODULE__{state: :running} = m, p) do
    target = target(m)
    point = {target.north, target.east}
    g = Guidance.los(p, m.from, point, Guidance.lookahead(target.radius))
    distance = dist(p, point)

    if distance <= target.radius or (g.length > 0 and g.along >= g.length) do
      arrived(m, point)
    else
      {%{m | guidance: guidance(m, g, distance)}, []}
    end
    |> then(fn {m, events} ->
      # the arrival's step also steers: on to the next leg at once
      if m.state == :running and events != [],
        do: {elem(step(m, p), 0), events},
        else: {m, events}
    end)
  end

  def step(%__MODULE__{} = m, _p), do: {m, []}

  defp arrived(m, point) do
    reached = {:reached, m.leg + 1}

    if m.leg + 1 >= length(m.waypoints),
      do: {%{m | state: :done}, [reached, :done]},
      else: {%{m | leg: m.leg + 1, from: point}, [reached]}
  end

  # the final waypoint is approached slowing down, so the vehicle stops on it
  defp guidance(m, g, distance) do
    target = target(m)
    last? = m.leg == length(m.waypoints) - 1
    speed = if last?, do: min(target.speed, max(@slowdown * distance, 0.05)), else: target.speed

    Map.merge(g, %{
      speed: speed,
      depth: target.depth,
      heading: target.heading,
      distance: distance
    })
  end

  @doc "As the wire shows it: `%{id, state, leg, waypoints}` (`leg` 1-based)."
  @spec public(t()) :: map()
  def public(%__MODULE__{} = m) do
    %{id: m.id, state: Atom.to_string(m.state), leg: m.leg + 1, waypoints: m.waypoints}
  end

  defp dist({a, b}, {c, d}), do: :math.sqrt((a - c) * (a - c) + (b - d) * (b - d))
  defp fmt(x), do: :erlang.float_to_binary(x * 1.0, decimals: 1)
  defp fmt_int(x), do: x |> round() |> Integer.to_string()
end
