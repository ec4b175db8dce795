defmodule Neptunus.Config.Settings do
  @moduledoc """
  The settings store's directory (`config :neptunus, :settings_dir`, see `Neptunus.Settings`):
  `NEPTUNUS_SETTINGS` (see `settings_dir!/2`).
  """

  alias Neptunus.Config

  @doc """
  `NEPTUNUS_SETTINGS`: the directory of the per-user and per-vehicle settings (relative to
  the working directory, created when first written), or `default` when unset — `settings`,
  beside the recordings' default `recordings`.

      iex> Neptunus.Config.Settings.settings_dir!(%{}, "settings")
      "settings"
      iex> Neptunus.Config.Settings.settings_dir!(%{"NEPTUNUS_SETTINGS" => " /var/lib/neptunus/settings "}, "settings")
      "/var/lib/neptunus/settings"
  """
  @spec settings_dir!(Config.env(), Path.t()) :: Path.t()
  def settings_dir!(env, default) do
    dir = env |> Map.get("NEPTUNUS_SETTINGS", default) |> String.trim()

    case dir != "" && File.stat(dir) do
      false ->
        Config.bad!("NEPTUNUS_SETTINGS", dir, "a directory")

      {:ok, %File.Stat{type: :directory}} ->
        dir

      {:ok, _} ->
        Config.bad!("NEPTUNUS_SETTINGS", dir, "a directory (this is a file)")

      {:error, :enoent} ->
        dir

      {:error, reason} ->
        Config.bad!("NEPTUNUS_SETTINGS", dir, "a usable directory (#{reason})")
    end
  end
end
