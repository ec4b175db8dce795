defmodule Neptunus.Navigation.Position do
  @moduledoc """
  Where the vehicle is: the position sources' reports, judged and fused into north/east
  position and velocity with their uncertainty. Pure; `Neptunus.Vehicle.Navigation` runs it
  live and `Neptunus.Scenario.Run` headless, on the same reports.

  ## Sources

  Each source is named (`:dvl`, `:usbl`, `:ardusub`, …) and reports (`report/4`):

    * `{:velocity, %{t, vx, vy, fom, covariance, altitude, valid, tracking}}` — a DVL's
      velocity over the bottom in the vehicle frame, `t` the time it was measured (the
      driver has taken its age off);
    * `{:fix, %{t, north, east, std, valid, frame}}` — a position (a USBL fix, or a
      vehicle's own estimate), `frame` naming whose origin it is in;
    * `{:dead_reckoning, %{x, y, z, std}}` — a DVL's own integrated position (shown, not
      fused: it is the same velocities again);
    * `{:link, :up}`, `{:link, {:down, reason}}` — its connection; `{:garbage, reason}` — a
      report that could not be read.

  The heading comes from navigation's heading filter (`heading/4`: estimate and standard
  deviation at a time), the depth from its depth filter (`depth/2`, shown with the position).

  ## What is rejected, and why (counted per source and reason)

    * `no_lock` — a DVL report without bottom lock (`velocity_valid: false`);
    * `water_track` — a water-tracking velocity (through the water, not over the ground);
    * `out_of_range` — a speed beyond `max_speed` (#{3.0} m/s: no small ROV does that);
    * `no_heading` — no heading estimate to turn the DVL's velocity into north and east;
    * `invalid_fix` — a fix the source itself says is not valid;
    * `innovation` — outside the filter's gate (`Neptunus.Navigation.PositionFilter`, 4 σ,
      and more than #{0.05} m/s or #{0.5} m off): a jump;
    * `too_old` — a fix older than the filter's history (#{3.0} s);
    * `frame` — a fix in another frame than the one the filter is in (a second absolute
      source with its own origin).

  **Re-acquisition**, as the depth and heading filters do: rejected readings that agree with
  each other are the truth after all when they persist — `confirm_velocity` (5) velocities
  within 0.15 m/s of each other, or `confirm_fix` (3) fixes within 3 σ (and at least 1 m) of
  each other once the vehicle's own motion in between is taken off. The filter's velocity or
  position is then reset to them (`reacquired` counts it).

  ## Frames

  The filter starts at the first usable report: on a DVL velocity at `(0, 0)` in the
  **local** frame (dead reckoning from where the vehicle was), on a fix at the fix, in its
  source's frame. The first `confirm_fix` agreeing fixes of an absolute source while in the
  local frame **re-anchor** it: the position moves into the fix's frame by the offset they
  agree on. Each change of frame increments `epoch` and records the `shift` (m, north and
  east) that took positions from the old frame into the new, so whoever holds a target in
  the old frame (position hold) moves it by the same shift: the vehicle is not sent
  anywhere by a change of bookkeeping.

  ## Valid, and "no position"

  The position is **valid** when the filter has one, its larger 1-σ semi-axis is at most
  `max_std` (#{3.0} m), and a DVL velocity was accepted in the last `velocity_stale`
  (#{2.0} s) or a fix in the last `fix_stale` (#{5.0} s) — and, started on fixes alone, at
  least two fixes agreed. Otherwise it is not, with a reason a pilot can read (`reason`).
  After `lost_after` (#{30.0} s) without either the estimate is dropped (a new frame
  starts with the next report: `epoch` changes with no shift).
  """

  alias Neptunus.Navigation.Matrix, as: M
  alias Neptunus.Navigation.PositionFilter, as: Filter

  @defaults %{
    max_speed: 3.0,
    gate: 4.0,
    velocity_min_gate: 0.05,
    fix_min_gate: 0.5,
    velocity_floor: 0.005,
    fix_floor: 0.1,
    confirm_velocity: 5,
    confirm_fix: 3,
    velocity_stale: 2.0,
    fix_stale: 5.0,
    lost_after: 30.0,
    max_std: 3.0,
    report_stale: 2.0,
    heading_window: 3.0
  }

  @reasons ~w(no_lock water_track out_of_range no_heading invalid_fix innovation too_old frame)a

  defmodule Source do
    @moduledoc false
    # One source's bookkeeping (see Neptunus.Navigation.Position).
    @type t :: %__MODULE__{
            name: atom(),
            kind: :velocity | :fix | nil,
            link: :unknown | :up | {:down, String.t()},
            last_at: float() | nil,
            accepted_at: float() | nil,
            reports: non_neg_integer(),
            accepted: non_neg_integer(),
            rejected: %{atom() => non_neg_integer()},
            garbage: non_neg_integer(),
            disconnects: non_neg_integer(),
            reacquired: non_neg_integer(),
            last_rejection: String.t() | nil,
            last_garbage: String.t() | nil,
            altitude: float() | nil,
            fom: float() | nil,
            std: float() | nil,
            innovation: [float()] | nil,
            dead_reckoning: map() | nil,
            run: list()
          }
    defstruct [
      :name,
      :kind,
      :last_at,
      :accepted_at,
      :last_rejection,
      :last_garbage,
      :altitude,
      :fom,
      :std,
      :innovation,
      :dead_reckoning,
      link: :unknown,
      reports: 0,
      accepted: 0,
      rejected: %{},
      garbage: 0,
      disconnects: 0,
      reacquired: 0,
      run: []
    ]
  end

  @enforce_keys [:filter, :config]
  defstruct [
    :filter,
    :config,
    :depth,
    :frame,
    :shift,
    sources: %{},
    headings: [],
    epoch: 0,
    fixes_agreed: 0,
    anchor_run: []
  ]

  @typedoc """
  * `filter` — the EKF; `config` — the settings (see the moduledoc)
  * `sources` — each source's bookkeeping, by name
  * `headings` — `{t, ψ, σ_ψ}` from navigation, newest first (the last `heading_window` s)
  * `depth` — the depth estimate (m) or nil
  * `frame` — whose origin the position is in (`:local`, or a fix source's frame), nil
    without an estimate; `epoch` counts frame changes, `shift` the last one's `{dn, de}`
  * `fixes_agreed` — fixes accepted since the filter started on one
  * `anchor_run` — `{t, offset, std}` of fixes seen in the local frame (re-anchoring)
  """
  @type t :: %__MODULE__{
          filter: Filter.t(),
          config: map(),
          depth: float() | nil,
          frame: atom() | nil,
          shift: {float(), float()} | nil,
          sources: %{atom() => Source.t()},
          headings: [{float(), float(), float()}],
          epoch: non_neg_integer(),
          fixes_agreed: non_neg_integer(),
          anchor_run: list()
        }

  @type report ::
          {:velocity, map()}
          | {:fix, map()}
          | {:dead_reckoning, map()}
          | {:link, :up | {:down, String.t()}}
          | {:garbage, String.t()}

  @doc "The rejection reasons."
  @spec reasons() :: [atom()]
  def reasons, do: @reasons

  @doc """
  A position estimator with no estimate. Options: `sources` (names expected, shown as
  waiting until they report), `q` and `window` (the filter's), and any of the settings in
  the moduledoc (`max_speed`, `gate`, `confirm_fix`, `fix_stale`, `max_std`, …).
  """
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    config =
      Enum.reduce(opts, @defaults, fn {key, value}, acc ->
        if Map.has_key?(@defaults, key), do: Map.put(acc, key, value), else: acc
      end)

    sources = Map.new(Keyword.get(opts, :sources, []), &{&1, %Source{name: &1}})
    filter = Filter.new(Keyword.take(opts, [:q, :window]))
    %__MODULE__{filter: filter, config: config, sources: sources}
  end

  @doc "The heading estimate `psi` (rad, or nil: none) with its standard deviation at `t`."
  @spec heading(t(), float(), float() | nil, float() | nil) :: t()
  def heading(pos, _t, nil, _std), do: pos

  def heading(%__MODULE__{} = pos, t, psi, std) do
    keep = pos.config.heading_window
    std = if is_number(std), do: std, else: 0.05

    headings = [
      {t * 1.0, psi * 1.0, std * 1.0}
      | Enum.take_while(pos.headings, fn {ht, _, _} -> ht > t - keep end)
    ]

    %{pos | headings: headings}
  end

  @doc "The depth estimate (m, or nil), shown with the position."
  @spec depth(t(), float() | nil) :: t()
  def depth(pos, depth), do: %{pos | depth: depth}

  @doc "A report from source `name` that arrived at `now` (s; see the moduledoc)."
  @spec report(t(), atom(), report(), float()) :: t()
  def report(pos, name, report, now) do
    source = Map.get(pos.sources, name, %Source{name: name})
    pos = %{pos | sources: Map.put(pos.sources, name, source)}
    take(pos, name, report, now)
  end

  defp take(pos, name, {:link, :up}, _now), do: update_source(pos, name, &%{&1 | link: :up})

  defp take(pos, name, {:link, {:down, reason}}, _now) do
    update_source(pos, name, fn s ->
      disconnects = if s.link == :up, do: s.disconnects + 1, else: s.disconnects
      %{s | link: {:down, reason}, disconnects: disconnects}
    end)
  end

  defp take(pos, name, {:garbage, reason}, now) do
    update_source(pos, name, &%{&1 | garbage: &1.garbage + 1, last_garbage: reason, last_at: now})
  end

  defp take(pos, name, {:dead_reckoning, dr}, now) do
    update_source(
      pos,
      name,
      &%{&1 | dead_reckoning: Map.take(dr, [:x, :y, :z, :std]), last_at: now}
    )
  end

  defp take(pos, name, {:velocity, v}, now) do
    pos =
      update_source(pos, name, fn s ->
        %{
          s
          | kind: :velocity,
            reports: s.reports + 1,
            last_at: now,
            altitude: v.altitude,
            fom: v.fom
        }
      end)

    speed = :math.sqrt(v.vx * v.vx + v.vy * v.vy)

    cond do
      Map.get(v, :tracking, :bottom) == :water ->
        reject(
          pos,
          name,
          :water_track,
          "water-tracking velocity (through the water, not over the ground)"
        )

      not v.valid ->
        reject(pos, name, :no_lock, no_lock(v.altitude))

      speed > pos.config.max_speed ->
        reject(
          pos,
          name,
          :out_of_range,
          "velocity #{fmt(speed)} m/s beyond #{fmt(pos.config.max_speed)} m/s"
        )

      true ->
        case heading_at(pos, v.t) do
          nil -> reject(pos, name, :no_heading, "no heading estimate to turn the DVL's velocity")
          {psi, psi_std} -> velocity(pos, name, v, psi, psi_std, now)
        end
    end
  end

  defp take(pos, name, {:fix, fix}, now) do
    pos =
      update_source(pos, name, fn s ->
        %{s | kind: :fix, reports: s.reports + 1, last_at: now, std: fix.std}
      end)

    if fix.valid,
      do: fix(pos, name, fix, now),
      else: reject(pos, name, :invalid_fix, "the source has no valid fix")
  end

  defp no_lock(altitude) when is_number(altitude) and altitude > 0,
    do: "no bottom lock (altitude #{fmt(altitude)} m)"

  defp no_lock(_altitude), do: "no bottom lock"

  # --- velocity ---

  defp velocity(pos, name, v, psi, psi_std, _now) do
    r = velocity_r(v, pos.config.velocity_floor)

    meas = %{
      t: v.t * 1.0,
      kind: :velocity,
      z: [v.vx, v.vy],
      r: r,
      psi: psi,
      psi_var: psi_std * psi_std
    }

    if Filter.started?(pos.filter) do
      opts = [gate: pos.config.gate, min_gate: pos.config.velocity_min_gate]

      case Filter.insert(pos.filter, meas, opts) do
        {:accepted, info, filter} ->
          %{pos | filter: filter} |> accepted(name, v.t, info)

        {:rejected, :innovation, info, _filter} ->
          velocity_miss(pos, name, meas, info)

        {:rejected, :too_old, _info, _filter} ->
          reject(pos, name, :too_old, "velocity older than the filter's history")
      end
    else
      {vn, ve} = to_ned(v.vx, v.vy, psi)
      var = max(M.at(r, 0, 0), M.at(r, 1, 1))
      filter = Filter.start(pos.filter, v.t, {{0.0, 0.0}, 1.0e-4}, {{vn, ve}, var})

      %{pos | filter: filter, frame: :local, epoch: pos.epoch + 1, shift: nil, anchor_run: []}
      |> accepted(name, v.t, %{y: [0.0, 0.0], d2: 0.0})
    end
  end

  defp velocity_r(%{covariance: [[a, b, _], [c, d, _], _]}, floor),
    do: [[max(a, floor * floor), b], [c, max(d, floor * floor)]]

  defp velocity_r(%{fom: fom}, floor) do
    sigma = max(fom, floor) * 1.0
    M.diag([sigma * sigma, sigma * sigma])
  end

  # rejected by the gate: a run of velocities that agree with each other is the truth
  defp velocity_miss(pos, name, meas, info) do
    source = pos.sources[name]
    run = extend_run(source.run, meas, fn a, b -> dist(a.z, b.z) <= 0.15 end)
    pos = update_source(pos, name, &%{&1 | run: run, innovation: info.y})

    if length(run) >= pos.config.confirm_velocity do
      {vn, ve} = to_ned(Enum.at(meas.z, 0), Enum.at(meas.z, 1), meas.psi)
      filter = Filter.reset_velocity(pos.filter, meas.t, {[vn, ve], meas.r})

      %{pos | filter: filter}
      |> update_source(name, &%{&1 | reacquired: &1.reacquired + 1, run: []})
      |> accepted(name, meas.t, info)
    else
      reject(
        pos,
        name,
        :innovation,
        "velocity jumped: rejected by the filter (#{length(run)} in a row)"
      )
    end
  end

  # --- fixes ---

  defp fix(pos, name, fix, now) do
    std = max(fix.std, pos.config.fix_floor)
    r = M.diag([std * std, std * std])
    meas = %{t: fix.t * 1.0, kind: :position, z: [fix.north, fix.east], r: r}
    frame = Map.get(fix, :frame, name)

    cond do
      not Filter.started?(pos.filter) ->
        filter =
          Filter.start(pos.filter, fix.t, {{fix.north, fix.east}, std * std}, {{0.0, 0.0}, 0.25})

        %{pos | filter: filter, frame: frame, epoch: pos.epoch + 1, shift: nil, fixes_agreed: 1}
        |> accepted(name, fix.t, %{y: [0.0, 0.0], d2: 0.0})

      pos.frame == :local ->
        anchor(pos, name, meas, frame, now)

      pos.frame != frame ->
        reject(
          pos,
          name,
          :frame,
          "a fix in frame #{frame} while the position is in frame #{pos.frame}"
        )

      true ->
        opts = [gate: pos.config.gate, min_gate: pos.config.fix_min_gate]

        case Filter.insert(pos.filter, meas, opts) do
          {:accepted, info, filter} ->
            %{pos | filter: filter, fixes_agreed: pos.fixes_agreed + 1}
            |> accepted(name, fix.t, info)

          {:rejected, :innovation, info, _} ->
            fix_miss(pos, name, meas, info)

          {:rejected, :too_old, _, _} ->
            reject(
              pos,
              name,
              :too_old,
              "fix older than the filter's #{fmt(pos.filter.window)} s history"
            )
        end
    end
  end

  # rejected fixes that agree with each other (the vehicle's own motion in between taken off)
  defp fix_miss(pos, name, meas, info) do
    source = pos.sources[name]
    with_offset = Map.put(meas, :offset, offset(pos, meas))
    run = extend_run(source.run, with_offset, &fixes_agree?/2)
    pos = update_source(pos, name, &%{&1 | run: run, innovation: info.y})

    if length(run) >= pos.config.confirm_fix do
      filter = Filter.reset_position(pos.filter, meas.t, {meas.z, meas.r})

      %{pos | filter: filter}
      |> update_source(name, &%{&1 | reacquired: &1.reacquired + 1, run: []})
      |> accepted(name, meas.t, info)
    else
      off = :math.sqrt(M.dot(info.y, info.y))

      reject(
        pos,
        name,
        :innovation,
        "fix #{fmt(off)} m off the estimate: rejected (#{length(run)} in a row)"
      )
    end
  end

  # in the local frame: fixes whose offsets from the estimate agree re-anchor the frame
  defp anchor(pos, name, meas, frame, _now) do
    entry = Map.put(meas, :offset, offset(pos, meas))
    run = extend_run(pos.anchor_run, entry, &fixes_agree?/2)
    pos = %{pos | anchor_run: run}

    if length(run) >= pos.config.confirm_fix do
      [dn, de] = mean_offset(run)
      {[n, e, _, _], _} = Filter.at(pos.filter, pos.filter.t)
      filter = Filter.reset_position(pos.filter, pos.filter.t, {[n + dn, e + de], meas.r})

      %{
        pos
        | filter: filter,
          frame: frame,
          epoch: pos.epoch + 1,
          shift: {dn, de},
          anchor_run: [],
          fixes_agreed: length(run)
      }
      |> accepted(name, meas.t, %{y: [0.0, 0.0], d2: 0.0})
    else
      update_source(
        pos,
        name,
        &%{
          &1
          | last_rejection:
              "anchoring the local frame (#{length(run)} of #{pos.config.confirm_fix} fixes)"
        }
      )
    end
  end

  # the fix minus the estimate at its time
  defp offset(pos, %{t: t, z: [zn, ze]}) do
    {[n, e, _, _], _} = position_at(pos.filter, t)
    [zn - n, ze - e]
  end

  # the state at `t`: from the snapshot at or before it (a past time), else predicted
  defp position_at(filter, t) do
    case Enum.find(filter.history, fn {ht, _, _} -> ht <= t end) do
      nil ->
        Filter.at(filter, t)

      {ht, x, p} ->
        {_, x, p} = Filter.predict({ht, x, p}, t, filter.q)
        {x, p}
    end
  end

  defp fixes_agree?(a, b) do
    sa = :math.sqrt(M.at(a.r, 0, 0))
    sb = :math.sqrt(M.at(b.r, 0, 0))
    dist(a.offset, b.offset) <= max(3.0 * (sa + sb), 1.0)
  end

  defp mean_offset(run) do
    n = length(run)
    [sn, se] = Enum.reduce(run, [0.0, 0.0], fn %{offset: [a, b]}, [x, y] -> [x + a, y + b] end)
    [sn / n, se / n]
  end

  # a run of entries each agreeing with the one before; one that does not starts a new run
  defp extend_run([last | _] = run, entry, agree?) do
    if agree?.(last, entry), do: [entry | run], else: [entry]
  end

  defp extend_run([], entry, _agree?), do: [entry]

  # --- bookkeeping ---

  defp accepted(pos, name, t, info) do
    update_source(pos, name, fn s ->
      %{
        s
        | accepted: s.accepted + 1,
          accepted_at: max(t, s.accepted_at || t),
          innovation: info.y,
          run: [],
          last_rejection: nil
      }
    end)
  end

  defp reject(pos, name, reason, text) do
    update_source(pos, name, fn s ->
      %{s | rejected: Map.update(s.rejected, reason, 1, &(&1 + 1)), last_rejection: text}
    end)
  end

  defp update_source(pos, name, fun) do
    source = Map.get(pos.sources, name, %Source{name: name})
    %{pos | sources: Map.put(pos.sources, name, fun.(source))}
  end

  # the heading estimate nearest to `t` within the window (nil: none)
  defp heading_at(%__MODULE__{headings: []}, _t), do: nil

  defp heading_at(%__MODULE__{headings: headings, config: c}, t) do
    {ht, psi, std} = Enum.min_by(headings, fn {ht, _, _} -> abs(ht - t) end)
    if abs(ht - t) <= c.heading_window, do: {psi, std}, else: nil
  end

  defp to_ned(vx, vy, psi) do
    {c, s} = {:math.cos(psi), :math.sin(psi)}
    {c * vx - s * vy, s * vx + c * vy}
  end

  defp dist([a, b], [c, d]), do: :math.sqrt((a - c) * (a - c) + (b - d) * (b - d))

  @doc """
  Drops an estimate no source has aided for `lost_after` s (at `now`); call it now and then
  (navigation does on every board sample).
  """
  @spec tick(t(), float()) :: t()
  def tick(%__MODULE__{} = pos, now) do
    if Filter.started?(pos.filter) and now - last_aided(pos) > pos.config.lost_after,
      do: %{
        pos
        | filter: Filter.clear(pos.filter),
          frame: nil,
          shift: nil,
          anchor_run: [],
          fixes_agreed: 0
      },
      else: pos
  end

  defp last_aided(pos) do
    pos.sources
    |> Map.values()
    |> Enum.map(& &1.accepted_at)
    |> Enum.reject(&is_nil/1)
    |> Enum.max(fn -> pos.filter.t || 0.0 end)
  end

  # --- views ----------------------------------------------------------------------------------

  @doc """
  The estimate at `now` for control: `%{valid, reason, north, east, velocity_north,
  velocity_east, std_north, std_east, covariance, frame, epoch, shift,
  velocity_measured}` — position and velocity nil without an estimate, `reason` nil when
  valid (else why not), `shift` the last frame change's `{dn, de}` (see the moduledoc),
  `velocity_measured` whether a velocity source (a DVL) is fresh.
  """
  @spec estimate(t(), float()) :: map()
  def estimate(%__MODULE__{} = pos, now) do
    {valid, reason} = validity(pos, now)

    base = %{
      valid: valid,
      reason: reason,
      frame: pos.frame,
      epoch: pos.epoch,
      shift: pos.shift,
      velocity_measured: fresh?(pos, :velocity, now, pos.config.velocity_stale)
    }

    case Filter.at(pos.filter, now) do
      nil ->
        Map.merge(base, %{
          north: nil,
          east: nil,
          velocity_north: nil,
          velocity_east: nil,
          std_north: nil,
          std_east: nil,
          covariance: nil
        })

      {[n, e, vn, ve], p} ->
        Map.merge(base, %{
          north: n,
          east: e,
          velocity_north: vn,
          velocity_east: ve,
          std_north: :math.sqrt(max(M.at(p, 0, 0), 0.0)),
          std_east: :math.sqrt(max(M.at(p, 1, 1), 0.0)),
          covariance: M.block(p, 0, 1)
        })
    end
  end

  defp validity(pos, now) do
    c = pos.config

    cond do
      not Filter.started?(pos.filter) ->
        {false, no_source_reason(pos, now)}

      true ->
        {[_, _, _, _], p} = Filter.at(pos.filter, now)
        {major, _, _} = M.ellipse(M.block(p, 0, 1))
        velocity_fresh = fresh?(pos, :velocity, now, c.velocity_stale)
        fix_fresh = fresh?(pos, :fix, now, c.fix_stale)

        cond do
          not velocity_fresh and not fix_fresh ->
            {false, "no position measurement for a while: #{sources_reason(pos, now)}"}

          major > c.max_std ->
            {false, "position uncertainty #{fmt(major)} m beyond #{fmt(c.max_std)} m"}

          not velocity_fresh and pos.frame != :local and pos.fixes_agreed < 2 ->
            {false, "waiting for a second fix to agree with the first"}

          true ->
            {true, nil}
        end
    end
  end

  defp fresh?(pos, kind, now, stale) do
    Enum.any?(Map.values(pos.sources), fn s ->
      s.kind == kind and s.accepted_at != nil and now - s.accepted_at <= stale
    end)
  end

  defp no_source_reason(pos, now) do
    if map_size(pos.sources) == 0,
      do: "no position source",
      else: "no position yet: #{sources_reason(pos, now)}"
  end

  defp sources_reason(pos, now) do
    pos.sources
    |> Map.values()
    |> Enum.sort_by(& &1.name)
    |> Enum.map(&"#{&1.name}: #{source_reason(&1, now, pos.config)}")
    |> Enum.join("; ")
  end

  defp source_reason(%Source{link: {:down, reason}}, _now, _c), do: "disconnected (#{reason})"

  defp source_reason(%Source{last_at: nil}, _now, _c), do: "no report yet"

  defp source_reason(%Source{} = s, now, c) do
    cond do
      now - s.last_at > c.report_stale -> "no report for #{fmt(now - s.last_at)} s"
      s.last_rejection != nil -> s.last_rejection
      s.accepted_at == nil and s.last_garbage != nil -> "unreadable reports (#{s.last_garbage})"
      s.accepted_at == nil -> "no usable report yet"
      true -> "last usable report #{fmt(now - s.accepted_at)} s ago"
    end
  end

  @doc """
  The position as telemetry shows it at `now` (see `NeptunusWeb.WireSchema`, `position`):
  the estimate with depth, the 1-σ ellipse, the frame, each source's state and the last
  innovations.
  """
  @spec status(t(), float()) :: map()
  def status(%__MODULE__{} = pos, now) do
    e = estimate(pos, now)

    ellipse =
      case e.covariance do
        nil ->
          nil

        cov ->
          cov |> M.ellipse() |> then(fn {a, b, angle} -> %{major: a, minor: b, angle: angle} end)
      end

    %{
      valid: e.valid,
      reason: e.reason,
      frame: e.frame && Atom.to_string(e.frame),
      epoch: e.epoch,
      north: e.north,
      east: e.east,
      depth: pos.depth,
      velocity_north: e.velocity_north,
      velocity_east: e.velocity_east,
      std_north: e.std_north,
      std_east: e.std_east,
      ellipse: ellipse,
      sources:
        pos.sources
        |> Map.values()
        |> Enum.sort_by(& &1.name)
        |> Enum.map(&source_status(&1, now, pos.config))
    }
  end

  defp source_status(%Source{} = s, now, c) do
    stale = if s.kind == :fix, do: c.fix_stale, else: c.velocity_stale
    down? = match?({:down, _}, s.link)
    valid = s.accepted_at != nil and now - s.accepted_at <= stale and not down?

    %{
      name: Atom.to_string(s.name),
      kind: s.kind && Atom.to_string(s.kind),
      state:
        if(valid,
          do: "valid",
          else: if(s.last_at == nil and s.link != :up, do: "waiting", else: "invalid")
        ),
      reason: if(valid, do: nil, else: source_reason(s, now, c)),
      connected: s.link == :up or (s.link == :unknown and s.last_at != nil),
      reports: s.reports,
      accepted: s.accepted,
      rejected: Map.new(s.rejected, fn {k, v} -> {Atom.to_string(k), v} end),
      garbage: s.garbage,
      disconnects: s.disconnects,
      reacquired: s.reacquired,
      altitude: s.altitude,
      fom: s.fom,
      std: s.std,
      innovation: s.innovation,
      dead_reckoning: s.dead_reckoning
    }
  end

  defp fmt(x) when is_number(x), do: :erlang.float_to_binary(x * 1.0, decimals: 1)
end
