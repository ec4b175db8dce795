defmodule NeptunusWeb.API do
  @moduledoc """
  The HTTP API under `/api` (a yaws appmod). JSON in, JSON out; errors are
  `{"error": reason}` with a 4xx status.

    * `GET /api/health` → `{"status": "ok", "version": v, "vehicles": [{"id", "board"}]}`
  """
  import NeptunusWeb.Yaws

  alias NeptunusWeb.Channels.Wire

  @doc false
  def out(arg) do
    method = http_request(arg(arg, :req), :method)
    path = arg(arg, :server_path) |> to_string()
    respond(route(method, path))
  rescue
    exception ->
      require Logger
      Logger.error("API request failed: " <> Exception.format(:error, exception, __STACKTRACE__))
      respond({500, %{error: "internal error"}})
  end

  @doc "The health document (also used by tests and the fleet channel)."
  @spec health() :: map()
  def health do
    %{
      status: "ok",
      version: Application.spec(:neptunus, :vsn) |> to_string(),
      vehicles: Neptunus.Fleet.list()
    }
  end

  defp route(:GET, "/api/health"), do: {200, health()}
  defp route(_method, "/api/health"), do: {405, %{error: "method not allowed: use GET"}}
  defp route(_method, path), do: {404, %{error: "no such API endpoint: #{path}"}}

  defp respond({status, body}) do
    [
      {:status, status},
      {:header, {:cache_control, ~c"no-store"}},
      {:content, ~c"application/json", Wire.encode_json(body)}
    ]
  end
end
