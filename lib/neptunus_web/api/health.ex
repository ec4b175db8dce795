defmodule NeptunusWeb.API.Health do
  @moduledoc """
  `GET /api/health` → `{"status": "ok", "version": v, "vehicles": [{"id", "board", "node",
  "status", "helm", "pilot", "link", "depth", "heading", "recording"}]}`: every vehicle of the
  fleet, with its node, unreachable ones too (`Neptunus.Fleet.directory/0`); on an SD-card
  image also `"firmware_update": {"result": "updated" | "rolled-back", "version", "reason",
  …}`, its last firmware update (`Neptunus.FirmwareRecord`). Open to anyone the endpoint
  serves (the installer, the card's updater and monitoring read it).
  """

  @doc "The node's health (see the moduledoc)."
  @spec show(tuple()) :: {200, map()}
  def show(_arg) do
    body = %{
      status: "ok",
      version: Application.spec(:neptunus, :vsn) |> to_string(),
      vehicles: Neptunus.Fleet.directory()
    }

    case Neptunus.FirmwareRecord.read(NeptunusWeb.Endpoint.Settings.get().firmware_record) do
      nil -> {200, body}
      record -> {200, Map.put(body, :firmware_update, record)}
    end
  end
end
