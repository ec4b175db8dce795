defmodule Neptunus.Navigation.PositionFilter do
  @moduledoc """
  The horizontal position filter: an extended Kalman filter of north/east position and
  velocity that takes **delayed measurements at the time they were made**. Pure;
  `Neptunus.Navigation.Position` runs it with the sources' bookkeeping.

  ## State and model

  `x = [n, e, vₙ, vₑ]` (m, m/s, NED) with covariance `P`. Constant velocity driven by white
  acceleration noise of spectral density `q` ((m/s²)²/Hz, default #{0.02}): over `dt`,
  `F = [[I, dt·I], [0, I]]`, `Q = q·[[dt³/3·I, dt²/2·I], [dt²/2·I, dt·I]]`. The thrust is
  not a model input: a small ROV's accelerations are a few cm/s², well inside `q`, and the
  DVL measures velocity directly.

  ## Measurements

    * **Velocity in the vehicle frame** (a DVL): `z = [v_x, v_y]`, `h(x, ψ) = R(ψ)ᵀ [vₙ, vₑ]`
      with the heading `ψ` *estimated* (by the heading filter) at the measurement's time.
      Linear in `x` for a given `ψ`, so `H = [[0, 0, cos ψ, sin ψ], [0, 0, −sin ψ, cos ψ]]`;
      the heading's own uncertainty `σ_ψ²` enters through the Jacobian of `h` in `ψ`,
      `J = [−sin ψ·vₙ + cos ψ·vₑ, −cos ψ·vₙ − sin ψ·vₑ]`, as extra measurement noise
      `R = R_dvl + σ_ψ² J Jᵀ` — the extended part of the filter: at 0.5 m/s a 1° heading
      error is 9 mm/s of sideways velocity, more than the DVL's own noise.
    * **Position** (a USBL fix, or a vehicle's own position): `z = [n, e]`, `H = [I, 0]`,
      `R` from the fix's standard deviation.

  The update is the standard one with `P` in Joseph form. Each measurement is **gated**
  (`insert/3`'s `gate` and `min_gate`): its squared Mahalanobis distance `d² = yᵀS⁻¹y` beyond
  `gate²` *and* the innovation's length beyond `min_gate` rejects it (the absolute floor
  keeps a filter that is very sure of itself from rejecting good readings).

  ## Delayed measurements

  A USBL fix arrives about half a second after the instant it measured, while the DVL's
  velocities keep coming. The filter keeps, for the last `window` s (default #{3.0}), a
  snapshot of its state after each measurement and the measurements themselves. A
  measurement older than the filter's time is applied where it belongs: the filter goes back
  to the last snapshot before it, applies it there (gated against the state *at that time*),
  and re-applies the later measurements in order (without gating them again: they were
  accepted). A measurement older than the window is refused (`:too_old`).

  `reset_position/3` and `reset_velocity/3` (re-acquisition after the gate has rejected a
  run of agreeing measurements: the filter was wrong, not they) go through the same path.
  """

  alias Neptunus.Navigation.Matrix, as: M

  @default_q 0.02
  @default_window 3.0

  @enforce_keys [:q, :window]
  defstruct [:q, :window, :t, :x, :p, history: [], log: []]

  @typedoc "A measurement (see the moduledoc); `t` in s."
  @type measurement ::
          %{
            t: float(),
            kind: :velocity,
            z: [float()],
            r: M.t(),
            psi: float(),
            psi_var: float()
          }
          | %{t: float(), kind: :position, z: [float()], r: M.t()}
          | %{t: float(), kind: :reset_position | :reset_velocity, z: [float()], r: M.t()}

  @typedoc "What a measurement did: its innovation `y` and squared Mahalanobis distance."
  @type info :: %{y: [float()], d2: float()}

  @typedoc """
  * `q` — process noise; `window` — how far back measurements are taken (s)
  * `t`, `x`, `p` — the state's time, mean and covariance (nil before `start/4`)
  * `history` — `{t, x, p}` after each measurement, newest first
  * `log` — the measurements applied, newest first
  """
  @type t :: %__MODULE__{
          q: float(),
          window: float(),
          t: float() | nil,
          x: [float()] | nil,
          p: M.t() | nil,
          history: [{float(), [float()], M.t()}],
          log: [measurement()]
        }

  @doc "A filter with no estimate. Options: `q`, `window` (see the moduledoc)."
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    %__MODULE__{
      q: Keyword.get(opts, :q, @default_q) * 1.0,
      window: Keyword.get(opts, :window, @default_window) * 1.0
    }
  end

  @doc "Whether the filter has an estimate."
  @spec started?(t()) :: boolean()
  def started?(%__MODULE__{x: x}), do: x != nil

  @doc "Forgets the estimate (keeps the settings)."
  @spec clear(t()) :: t()
  def clear(%__MODULE__{} = f), do: %{f | t: nil, x: nil, p: nil, history: [], log: []}

  @doc """
  Starts the estimate at `t` with position `{n, e}` and velocity `{vₙ, vₑ}`, each with its
  variance (m², (m/s)², the same on both axes).
  """
  @spec start(t(), float(), {{float(), float()}, float()}, {{float(), float()}, float()}) ::
          t()
  def start(%__MODULE__{} = f, t, {{n, e}, pos_var}, {{vn, ve}, vel_var}) do
    x = [n * 1.0, e * 1.0, vn * 1.0, ve * 1.0]
    p = M.diag([pos_var, pos_var, vel_var, vel_var])
    %{f | t: t * 1.0, x: x, p: p, history: [{t * 1.0, x, p}], log: []}
  end

  @doc """
  Applies a measurement, at its own time (see the moduledoc). Options `gate` (σ, default 4)
  and `min_gate` (the innovation's length in the measurement's unit, default 0). Returns
  `{:accepted, info, filter}` or `{:rejected, reason, info | nil, filter}` with the filter
  unchanged; reasons `:innovation`, `:too_old`, `:not_started`.
  """
  @spec insert(t(), measurement(), keyword()) ::
          {:accepted, info(), t()} | {:rejected, atom(), info() | nil, t()}
  def insert(f, meas, opts \\ [])

  def insert(%__MODULE__{x: nil} = f, _meas, _opts), do: {:rejected, :not_started, nil, f}

  def insert(%__MODULE__{} = f, %{t: t} = meas, opts) when t >= f.t do
    state = predict({f.t, f.x, f.p}, t, f.q)

    case apply_measurement(state, meas, gate_opts(opts)) do
      {:ok, {_, x, p}, info} ->
        f = %{
          f
          | t: t * 1.0,
            x: x,
            p: p,
            history: [{t * 1.0, x, p} | f.history],
            log: [meas | f.log]
        }

        {:accepted, info, trim(f)}

      {:rejected, info} ->
        {:rejected, :innovation, info, f}
    end
  end

  def insert(%__MODULE__{} = f, %{t: t} = meas, opts) do
    case Enum.find(f.history, fn {ht, _, _} -> ht <= t end) do
      nil -> {:rejected, :too_old, nil, f}
      base -> replay(f, base, meas, gate_opts(opts))
    end
  end

  defp gate_opts(opts),
    do: {Keyword.get(opts, :gate, 4.0) * 1.0, Keyword.get(opts, :min_gate, 0.0) * 1.0}

  # back to the snapshot `base` (at or before the measurement), then every later measurement
  # in time order with the new one among them; only the new one is gated
  defp replay(f, {bt, _, _} = base, meas, gate) do
    later = f.log |> Enum.filter(&(&1.t > bt)) |> Enum.reverse()
    {before, rest} = Enum.split_while(later, &(&1.t <= meas.t))
    entries = Enum.map(before, &{:old, &1}) ++ [{:new, meas}] ++ Enum.map(rest, &{:old, &1})
    kept_history = Enum.drop_while(f.history, fn {ht, _, _} -> ht > bt end)

    result =
      Enum.reduce_while(entries, {base, kept_history, nil}, fn {age, m}, {state, history, info} ->
        state = predict(state, m.t, f.q)
        gate = if age == :new, do: gate, else: :none

        case apply_measurement(state, m, gate) do
          {:ok, {t, x, p} = state, new_info} ->
            {:cont, {state, [{t, x, p} | history], if(age == :new, do: new_info, else: info)}}

          {:rejected, new_info} ->
            {:halt, {:rejected, new_info}}
        end
      end)

    case result do
      {:rejected, info} ->
        {:rejected, :innovation, info, f}

      {{t, x, p}, history, info} ->
        log = Enum.sort_by([meas | f.log], & &1.t, :desc)
        {:accepted, info, trim(%{f | t: t, x: x, p: p, history: history, log: log})}
    end
  end

  # keep a snapshot at or before `t - window` and everything after it
  defp trim(%__MODULE__{t: now, window: w} = f) do
    {recent, old} = Enum.split_while(f.history, fn {ht, _, _} -> ht >= now - w end)
    history = recent ++ Enum.take(old, 1)
    {oldest, _, _} = List.last(history)
    %{f | history: history, log: Enum.filter(f.log, &(&1.t > oldest))}
  end

  @doc """
  Re-acquires the position at `t`: the position becomes `{n, e}` with covariance `r` (2×2),
  its correlation with the velocity is dropped; the later measurements are re-applied.
  """
  @spec reset_position(t(), float(), {[float()], M.t()}) :: t()
  def reset_position(f, t, {z, r}), do: reset(f, %{t: t * 1.0, kind: :reset_position, z: z, r: r})

  @doc "Re-acquires the velocity at `t` (NED `[vₙ, vₑ]`, covariance `r`), as `reset_position/3`."
  @spec reset_velocity(t(), float(), {[float()], M.t()}) :: t()
  def reset_velocity(f, t, {z, r}), do: reset(f, %{t: t * 1.0, kind: :reset_velocity, z: z, r: r})

  defp reset(f, meas) do
    case insert(f, meas, []) do
      {:accepted, _info, f} -> f
      {:rejected, _reason, _info, f} -> f
    end
  end

  @doc """
  The estimate at `t` (predicted from the last measurement, not stored): `{x, p}` or nil
  before `start/4`.
  """
  @spec at(t(), float()) :: {[float()], M.t()} | nil
  def at(%__MODULE__{x: nil}, _t), do: nil

  def at(%__MODULE__{} = f, t) do
    {_, x, p} = predict({f.t, f.x, f.p}, max(t, f.t), f.q)
    {x, p}
  end

  # --- the filter's steps -------------------------------------------------------------------

  @doc false
  # the constant-velocity prediction of a `{t, x, p}` state to `t1`
  @spec predict({float(), [float()], M.t()}, float(), float()) :: {float(), [float()], M.t()}
  def predict({t0, x, p}, t1, _q) when t1 <= t0, do: {t0, x, p}

  def predict({t0, [n, e, vn, ve], p}, t1, q) do
    dt = t1 - t0
    f = [[1.0, 0.0, dt, 0.0], [0.0, 1.0, 0.0, dt], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
    a = q * dt * dt * dt / 3.0
    b = q * dt * dt / 2.0
    c = q * dt
    qm = [[a, 0.0, b, 0.0], [0.0, a, 0.0, b], [b, 0.0, c, 0.0], [0.0, b, 0.0, c]]
    p = f |> M.mul(p) |> M.mul(M.transpose(f)) |> M.add(qm) |> M.symmetric()
    {t1 * 1.0, [n + vn * dt, e + ve * dt, vn, ve], p}
  end

  defp apply_measurement({t, x, p}, %{kind: kind, z: z, r: r}, _gate)
       when kind in [:reset_position, :reset_velocity] do
    [n, e, vn, ve] = x

    x =
      case {kind, z} do
        {:reset_position, [zn, ze]} -> [zn, ze, vn, ve]
        {:reset_velocity, [zn, ze]} -> [n, e, zn, ze]
      end

    block = if kind == :reset_position, do: 0, else: 2

    p =
      for i <- 0..3 do
        for j <- 0..3 do
          cond do
            i in block..(block + 1) and j in block..(block + 1) -> M.at(r, i - block, j - block)
            i in block..(block + 1) or j in block..(block + 1) -> 0.0
            true -> M.at(p, i, j)
          end
        end
      end

    {:ok, {t, x, p}, %{y: [0.0, 0.0], d2: 0.0}}
  end

  defp apply_measurement({t, [_, _, vn, ve] = x, p}, %{kind: :velocity} = m, gate) do
    {c, s} = {:math.cos(m.psi), :math.sin(m.psi)}
    h = [[0.0, 0.0, c, s], [0.0, 0.0, -s, c]]
    predicted = [c * vn + s * ve, -s * vn + c * ve]
    j = [-s * vn + c * ve, -c * vn - s * ve]
    r = M.add(m.r, M.scale(for(a <- j, do: for(b <- j, do: a * b)), m.psi_var))
    update({t, x, p}, h, predicted, m.z, r, gate)
  end

  defp apply_measurement({t, [n, e, _, _] = x, p}, %{kind: :position} = m, gate) do
    h = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]
    update({t, x, p}, h, [n, e], m.z, m.r, gate)
  end

  defp update({t, x, p}, h, predicted, z, r, gate) do
    y = Enum.zip_with(z, predicted, &-/2)
    ht = M.transpose(h)
    s = h |> M.mul(p) |> M.mul(ht) |> M.add(r)

    case M.inv2(s) do
      nil ->
        {:rejected, %{y: y, d2: :infinity}}

      s_inv ->
        d2 = M.dot(y, M.mulv(s_inv, y))
        info = %{y: y, d2: d2}

        if gated_out?(gate, y, d2) do
          {:rejected, info}
        else
          k = p |> M.mul(ht) |> M.mul(s_inv)
          x = Enum.zip_with(x, M.mulv(k, y), &+/2)
          i_kh = M.sub(M.identity(4), M.mul(k, h))

          p =
            i_kh
            |> M.mul(p)
            |> M.mul(M.transpose(i_kh))
            |> M.add(k |> M.mul(r) |> M.mul(M.transpose(k)))
            |> M.symmetric()

          {:ok, {t, x, p}, info}
        end
    end
  end

  defp gated_out?(:none, _y, _d2), do: false

  defp gated_out?({gate, min_gate}, y, d2) do
    length = :math.sqrt(M.dot(y, y))
    d2 > gate * gate and length > min_gate
  end
end
