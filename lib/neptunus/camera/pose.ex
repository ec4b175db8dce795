defmodule Neptunus.Camera.Pose do
  @moduledoc """
  What the simulated camera (`sim`) draws from: the vehicle's true pose, velocities and
  devices, as a simulator knows them.

  The simulators (`Neptunus.Vehicle.Board.Simulated`, the SITL board's
  `Neptunus.Vehicle.Board.OpenROV.SITL.Device`) publish it at every step on `topic/1` — a
  broadcast that costs them three table lookups when nobody listens — and the vehicle's camera
  process subscribes while it renders. So the picture follows the simulator at its own
  rate and no video work ever runs in the board, control or helm processes. The simulated
  position devices (`Neptunus.Sim.UGPSServer`, `Neptunus.Sim.DVLServer`) follow it too
  (`Neptunus.PubSub.Follow`, again after a PubSub restart).

  A pose: `x, y, z` (m, NED), `phi, theta, psi` (rad), `u, v, w` (m/s, body), `p, q, r`
  (rad/s), `lights`, `laser` (0..1) and `tilt` (rad, up > 0).
  """

  alias Neptunus.PubSub

  @type t :: %{
          x: float(),
          y: float(),
          z: float(),
          phi: float(),
          theta: float(),
          psi: float(),
          u: float(),
          v: float(),
          w: float(),
          p: float(),
          q: float(),
          r: float(),
          lights: float(),
          laser: float(),
          tilt: float()
        }

  @dyn_fields [:x, :y, :z, :phi, :theta, :psi, :u, :v, :w, :p, :q, :r]
  @fields @dyn_fields ++ [:lights, :laser, :tilt]

  @doc "The topic a vehicle's simulator publishes its pose on (event `\"pose\"`)."
  @spec topic(String.t()) :: String.t()
  def topic(id), do: "sim_pose:" <> id

  @doc """
  Publishes the pose of `dyn` (a `Neptunus.Dynamics.State` or its map) with the devices
  `lights`, `laser` (0..255) and `tilt` (rad).
  """
  @spec publish(String.t(), map(), %{lights: number(), laser: number(), tilt: number()}) :: :ok
  def publish(id, dyn, devices) do
    topic = topic(id)
    # nothing built while no camera renders this vehicle (the simulator's usual step)
    if PubSub.subscriber_count(topic) > 0,
      do: PubSub.broadcast(topic, "pose", new(dyn, devices)),
      else: :ok
  end

  @doc """
  A pose from a dynamics state and the devices (pure).

      iex> pose = Neptunus.Camera.Pose.new(%{x: 1, y: 2, z: 3, phi: 0, theta: 0, psi: 0.5,
      ...>   u: 0, v: 0, w: 0, p: 0, q: 0, r: 0}, %{lights: 255, laser: 0, tilt: 0.1})
      iex> {pose.z, pose.lights, pose.tilt}
      {3.0, 1.0, 0.1}
  """
  @spec new(map(), %{lights: number(), laser: number(), tilt: number()}) :: t()
  def new(dyn, %{lights: lights, laser: laser, tilt: tilt}) do
    @dyn_fields
    |> Map.new(&{&1, Map.fetch!(dyn, &1) * 1.0})
    |> Map.merge(%{lights: lights / 255, laser: laser / 255, tilt: tilt * 1.0})
  end

  @doc """
  The pose as the camera port program reads it: `p` and 15 big-endian doubles
  (`c_src/neptunus_camera.c`).
  """
  @spec encode(t()) :: binary()
  def encode(pose), do: for(f <- @fields, into: "p", do: <<Map.fetch!(pose, f)::float-64>>)
end
