defmodule Neptunus.Sim.Live do
  @moduledoc """
  The live simulator's controls on topic `vehicle:<id>` (`sim_reset`, `sim_set`): payload
  validation and the action on the vehicle's `Neptunus.Vehicle.Board.Simulated`.

  Authorisation is not decided here: the vehicle channel runs `command/3` through
  `Neptunus.Vehicle.Helm.command/4`, like every pilot-only command, so only the pilot can
  reset or change the simulation and no handover can come between the check and the action.

    * `sim_reset`, payload `{}` — the vehicle back to its initial state (pose, at rest;
      the current and tether length set since are kept). The thrusters are stopped first
      (`stopped` with reason `sim_reset`): a vehicle put back at its start should not carry on
      with the old command.
    * `sim_set`, payload with any of `paused` (boolean: freeze or resume simulated time),
      `current` (`[n, e, d]` m/s NED, each within ±5), `tether_length` (m, 0..1000).

  Both reply `{:ok, %{sim: status}}` with `status` =
  `%{vehicle, t, dt, current: [n, e, d], tether_length, noise, seed, paused}`.
  Errors: `"<event> is only available on a simulated vehicle (board: uart)"`, unknown or
  missing fields, wrong types or ranges (field named, see `Neptunus.Validate`).
  """

  alias Neptunus.Fleet
  alias Neptunus.Validate, as: V
  alias Neptunus.Vehicle.{Board, Control}

  @events ["sim_reset", "sim_set"]
  @set_fields ~w(paused current tether_length)

  @doc "The client events handled here."
  @spec events() :: [String.t()]
  def events, do: @events

  @doc "Carries out `event` (`sim_reset` or `sim_set`) with its untrusted JSON `payload`."
  @spec command(String.t(), String.t(), term()) :: {:ok, map()} | {:error, String.t()}
  def command(id, event, payload) when event in @events do
    with :ok <- simulated(id, event),
         {:ok, command} <- validate(event, payload) do
      if command == :reset, do: {:ok, _} = Control.stop(id, "sim_reset")
      {:ok, status} = Board.Simulated.command(id, command)
      {:ok, %{sim: status}}
    end
  end

  @doc """
  Validates a payload (pure).

      iex> Neptunus.Sim.Live.validate("sim_set", %{"current" => [0.1, 0, 0], "paused" => true})
      {:ok, {:set, %{current: {0.1, 0.0, 0.0}, paused: true}}}

      iex> Neptunus.Sim.Live.validate("sim_set", %{"current" => [9, 0, 0]})
      {:error, "current[0] must be a number in [-5, 5], got 9"}
  """
  @spec validate(String.t(), term()) :: {:ok, Board.Simulated.command()} | {:error, String.t()}
  def validate("sim_reset", payload) do
    with :ok <- V.object(payload, "", [], []), do: {:ok, :reset}
  end

  def validate("sim_set", payload) do
    with :ok <- V.object(payload, "", [], @set_fields),
         :ok <- some(payload),
         {:ok, paused} <- V.optional(payload, "", "paused", nil, &V.boolean/2),
         {:ok, current} <- V.optional(payload, "", "current", nil, &current/2),
         {:ok, tether} <-
           V.optional(payload, "", "tether_length", nil, &V.number(&1, &2, min: 0, max: 1000)) do
      changes =
        [paused: paused, current: current, tether_length: tether]
        |> Enum.reject(fn {_, value} -> is_nil(value) end)
        |> Map.new()

      {:ok, {:set, changes}}
    end
  end

  defp some(payload) do
    if map_size(payload) > 0,
      do: :ok,
      else: {:error, "sim_set needs at least one of: #{Enum.join(Enum.sort(@set_fields), ", ")}"}
  end

  defp current(value, path) do
    with {:ok, [n, e, d]} <- V.vector(value, path, 3, min: -5, max: 5), do: {:ok, {n, e, d}}
  end

  defp simulated(id, event) do
    case Enum.find(Fleet.list(), &(&1.id == id)) do
      %{board: :simulated} ->
        :ok

      %{board: board} ->
        {:error,
         "#{event} is only available on a simulated vehicle " <>
           "(board: #{board |> inspect() |> String.trim_leading(":")})"}

      nil ->
        {:error, "unknown vehicle: #{id}"}
    end
  end
end
