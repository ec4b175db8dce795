defmodule NeptunusWeb.API.Health do
  @moduledoc """
  `GET /api/health` → `{"status": "ok", "version": v, "vehicles": [{"id", "board", "node",
  "status", "helm", "pilot", "link", "depth", "heading", "recording"}]}`: every vehicle of the
  fleet, with its node, unreachable ones too (`Neptunus.Fleet.directory/0`). Open to anyone
  the endpoint serves (the installer and monitoring read it).
  """

  @doc "The node's health (see the moduledoc)."
  @spec show(tuple()) :: {200, map()}
  def show(_arg) do
    {200,
     %{
       status: "ok",
       version: Application.spec(:neptunus, :vsn) |> to_string(),
       vehicles: Neptunus.Fleet.directory()
     }}
  end
end
