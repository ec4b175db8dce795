defmodule Neptunus.Sim do
  @moduledoc """
  The simulated vehicle as a pure value: the dynamics' state, the parameters, the thruster
  command in force, and how it is measured. Every simulator — the live simulated board, the
  SITL board behind a pseudo-terminal, the headless scenario runner — steps the same
  `t:t/0` with `step/2` and reads it with `sample/1`, so what runs headless is what the pilot
  sees.

  Beyond the dynamics (`Neptunus.Dynamics`), it models the water surface (the vehicle cannot
  rise above z = 0; upward speed is cancelled there) and a simple power model for the
  voltage/current measurements (12.6 V battery with 0.25 Ω internal resistance, 0.3 A idle,
  2 A per thruster at full command).
  """

  alias Neptunus.{Allocation, Dynamics}

  @enforce_keys [:params, :dyn, :thrusters, :dt]
  defstruct [:params, :dyn, :thrusters, :dt, steps: 0]

  @typedoc "`dt` is the integration step in s; `steps` counts steps since start (t = steps · dt)."
  @type t :: %__MODULE__{
          params: Dynamics.Params.t(),
          dyn: Dynamics.State.t(),
          thrusters: Allocation.thrusters(),
          dt: float(),
          steps: non_neg_integer()
        }

  @doc """
  A new simulation. Options: `:dt` (s, default 0.01), `:initial` (keyword of
  `Dynamics.State` fields, default depth 1 m at rest), `:params` (default `:thesis_4dof`).
  """
  @spec new(keyword()) :: t()
  def new(opts \\ []) do
    %__MODULE__{
      params: Dynamics.params(Keyword.get(opts, :params, :thesis_4dof)),
      dyn: struct(Dynamics.State, Keyword.get(opts, :initial, z: 1.0)),
      thrusters: Allocation.neutral(),
      dt: Keyword.get(opts, :dt, 0.01)
    }
  end

  @doc "Sets the thruster command in force (values in [-1, 1])."
  @spec command(t(), Allocation.thrusters()) :: t()
  def command(sim, thrusters), do: %{sim | thrusters: thrusters}

  @doc "Advances the simulation by `n` steps of `dt`."
  @spec step(t(), pos_integer()) :: t()
  def step(%__MODULE__{} = sim, n \\ 1) do
    tau = Dynamics.tau_from_thrusters(sim.thrusters, sim.params)

    dyn =
      Enum.reduce(1..n, sim.dyn, fn _, dyn ->
        dyn |> Dynamics.step(tau, sim.dt, sim.params) |> surface()
      end)

    %{sim | dyn: dyn, steps: sim.steps + n}
  end

  @doc "Simulated time in s."
  @spec time(t()) :: float()
  def time(%__MODULE__{steps: steps, dt: dt}), do: steps * dt

  @doc "What a board would report now: measurements and the true state (see `Neptunus.Vehicle.Board`)."
  @spec sample(t()) :: Neptunus.Vehicle.Board.sample()
  def sample(%__MODULE__{dyn: dyn, thrusters: thr} = sim) do
    current = 0.3 + 2.0 * (abs(thr.port) + abs(thr.vertical) + abs(thr.starboard))

    %{
      t: time(sim),
      measurement: %{
        depth: dyn.z,
        heading: Dynamics.heading(dyn),
        roll: dyn.phi,
        pitch: dyn.theta,
        voltage: 12.6 - 0.25 * current,
        current: current
      },
      sim: Map.from_struct(dyn)
    }
  end

  defp surface(%Dynamics.State{z: z} = dyn) when z < 0.0, do: %{dyn | z: 0.0, w: max(dyn.w, 0.0)}
  defp surface(dyn), do: dyn
end
