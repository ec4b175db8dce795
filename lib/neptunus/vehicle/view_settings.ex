defmodule Neptunus.Vehicle.ViewSettings do
  @moduledoc """
  A vehicle's settings that every page applies the same way, whoever looks: today the camera
  image rotation (the camera is mounted as it is on this vehicle, whatever the device). Kept
  on the server (`Neptunus.Settings`, scope `{:vehicle, id}`, key `"camera.rotation"`), sent
  in the vehicle channel's join snapshot (`settings`) and broadcast on `"vehicle:<id>"` as
  `vehicle_settings` `%{camera_rotation}` when it changes, so every open page turns its image
  at once.

  Who may change it is the caller's business (the vehicle channel: the user who pilots or the
  main station).
  """

  alias Neptunus.{PubSub, Settings}
  alias Neptunus.Vehicle.Telemetry

  @rotations [0, 90, 180, 270]
  @rotation_key "camera.rotation"

  @doc "The camera rotations a page can show (degrees, clockwise)."
  @spec rotations() :: [0 | 90 | 180 | 270]
  def rotations, do: @rotations

  @doc "Vehicle `id`'s settings: `%{camera_rotation}` (0 unless one is stored)."
  @spec get(String.t()) :: %{camera_rotation: 0 | 90 | 180 | 270}
  def get(id) do
    rotation =
      case Settings.get({:vehicle, id}, @rotation_key) do
        {:ok, r} when r in @rotations -> r
        _ -> 0
      end

    %{camera_rotation: rotation}
  catch
    :exit, _ -> %{camera_rotation: 0}
  end

  @doc """
  Validates the untrusted `%{"value" => degrees}` (0, 90, 180 or 270), stores it and
  broadcasts `vehicle_settings`. `{:ok, %{camera_rotation}}` or `{:error, reason}` (nothing
  changed).
  """
  @spec set_camera_rotation(String.t(), term()) ::
          {:ok, %{camera_rotation: 0 | 90 | 180 | 270}} | {:error, String.t()}
  def set_camera_rotation(id, %{"value" => value}) when value in @rotations do
    with :ok <- Settings.put({:vehicle, id}, @rotation_key, value) do
      settings = %{camera_rotation: value}
      PubSub.broadcast(Telemetry.topic(id), "vehicle_settings", settings)
      {:ok, settings}
    end
  end

  def set_camera_rotation(_id, %{"value" => value}),
    do: {:error, "value must be one of 0, 90, 180, 270 (degrees), got #{inspect(value)}"}

  def set_camera_rotation(_id, _payload),
    do: {:error, "set_camera_rotation needs value (0, 90, 180 or 270 degrees)"}
end
