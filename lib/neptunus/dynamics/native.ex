defmodule Neptunus.Dynamics.Native do
  @moduledoc """
  The simulator's inner loop in C (`c_src/neptunus_dynamics_nif.c`, built by `mix compile`
  into `priv/neptunus_dynamics_nif.so`): `run/9` performs `n` steps of `Neptunus.Sim` —
  thruster lag, thrust, one RK4 step of `Neptunus.Dynamics`, angle wrapping, the water
  surface — for a constant current, about ten times faster than the same arithmetic on the
  BEAM.

  It is the same model, not a second one: the C code transcribes `Neptunus.Dynamics`
  operation by operation in the same order, without fused multiply-add and with the same
  libm functions, so its results are **bit-identical** to the Elixir code
  (`test/neptunus/dynamics/native_test.exs` runs both on random states, forces and
  parameter sets and compares every bit). The Elixir code stays the reference and the
  fallback: when the library is missing or fails to load, `available?/0` is false and
  `Neptunus.Sim` steps in Elixir.

  Why a NIF and not a port: the work per call is a few microseconds of arithmetic on
  copies of its arguments — no I/O, no allocation but the result, no state — and a port's
  message round trip would cost more than the steps. Calls are bounded (`Neptunus.Sim` runs
  at most 1 000 steps, about a millisecond, per call) and report their time to the
  scheduler. `Neptunus.Sim` uses it only when asked (`native: true`); the headless runner
  asks, the live boards do not by default.
  """

  @on_load :load
  @library ~c"neptunus_dynamics_nif"

  @doc false
  def load do
    path = :filename.join(priv_dir(), @library)

    case :erlang.load_nif(path, 0) do
      :ok ->
        _ = :persistent_term.erase({__MODULE__, :load_error})
        :ok

      {:error, {reason, text}} ->
        # the module still loads; available?/0 answers false and the Elixir code runs
        :persistent_term.put({__MODULE__, :load_error}, {reason, List.to_string(text)})
        :ok
    end
  end

  defp priv_dir do
    case :code.priv_dir(:neptunus) do
      {:error, :bad_name} -> ~c"priv"
      dir -> dir
    end
  end

  @doc "Whether the C library is loaded."
  @spec available?() :: boolean()
  def available?, do: load_error() == nil

  @doc "Why the library did not load (`nil` when it did)."
  @spec load_error() :: {atom(), String.t()} | nil
  def load_error, do: :persistent_term.get({__MODULE__, :load_error}, nil)

  @typedoc "`{x, y, z, phi, theta, psi, u, v, w, p, q, r}` (see `Neptunus.Dynamics.State`)"
  @type state12 :: tuple()

  @doc """
  `n` (1..100 000) steps of `dt`: thruster `forces` follow `targets` with `lags`
  (`{decay, mean}`, see `Neptunus.Dynamics.Thruster.lag/2`), the thrust plus `tau_ext`
  drives one RK4 step in the water `current` (NED), then `phi` and `psi` are wrapped and the
  surface holds `z ≥ 0`. `kernel` is `params.compiled.native`.

  Returns `{state, forces}`, or `{:singular, theta}` when pitch reaches ±90°. Raises
  `ArgumentError` on malformed arguments (wrong sizes, non-numbers).
  """
  @spec run(
          binary(),
          state12(),
          [float()],
          [float()],
          [{float(), float()}],
          tuple(),
          tuple(),
          float(),
          pos_integer()
        ) :: {state12(), [float()]} | {:singular, float()}
  def run(_kernel, _state, _forces, _targets, _lags, _tau_ext, _current, _dt, _n),
    do: :erlang.nif_error({:not_loaded, load_error()})
end
