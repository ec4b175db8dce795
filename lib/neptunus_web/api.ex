defmodule NeptunusWeb.API do
  @moduledoc """
  The HTTP API under `/api` (a yaws appmod): the router. JSON in, JSON out; errors are
  `{"error": reason}` with a 4xx status. Each resource is a module (`NeptunusWeb.API.*`)
  whose functions take the request (yaws' `#arg{}`) and return the answer
  (`NeptunusWeb.API.Response`); its moduledoc says what it takes and answers:

  | Path                                 | Methods                       | Resource         |
  |--------------------------------------|-------------------------------|------------------|
  | `/api/health`                        | GET                           | `API.Health`     |
  | `/api/login`                         | POST                          | `API.Login`      |
  | `/api/session`                       | GET                           | `API.Session`    |
  | `/api/recordings[/<vehicle>/<name>]` | GET; GET, DELETE for one      | `API.Recordings` |
  | `/api/settings[/<key>]`              | GET; GET, PUT, DELETE for one | `API.Settings`   |
  | `/api/snapshots[/<vehicle>/<name>]`  | GET                           | `API.Snapshots`  |
  | `/api/vehicles/<id>/snapshot`        | POST                          | `API.Snapshots`  |

  A path not listed is answered 404, a method its path does not take 405 (naming those it
  takes). A resource that raises is answered 500 "internal error", and the error logged.
  What a request may do is read from it by `NeptunusWeb.API.Request` (its token, its
  `Origin`). See docs/API.md.
  """
  import NeptunusWeb.Endpoint.Yaws

  require Logger

  alias NeptunusWeb.API.{Health, Login, Recordings, Response, Session, Settings, Snapshots}

  @doc false
  def out(arg) do
    method = http_request(arg(arg, :req), :method)
    path = arg(arg, :server_path) |> to_string()
    Response.respond(route(method, path, arg))
  rescue
    exception ->
      Logger.error(
        "API request failed: " <>
          Neptunus.Log.safe(Exception.format(:error, exception, __STACKTRACE__))
      )

      Response.respond({500, %{error: "internal error"}})
  end

  defp route(:GET, "/api/health", arg), do: Health.show(arg)
  defp route(_method, "/api/health", _arg), do: not_allowed("GET")
  defp route(:POST, "/api/login", arg), do: Login.create(arg)
  defp route(_method, "/api/login", _arg), do: not_allowed("POST")
  defp route(:GET, "/api/session", arg), do: Session.show(arg)
  defp route(_method, "/api/session", _arg), do: not_allowed("GET")
  defp route(:GET, "/api/recordings", arg), do: Recordings.index(arg)
  defp route(:GET, "/api/recordings/" <> rest, arg), do: Recordings.show(arg, parts(rest))
  defp route(:DELETE, "/api/recordings/" <> rest, arg), do: Recordings.delete(arg, parts(rest))

  defp route(_method, "/api/recordings" <> _, _arg),
    do: not_allowed("GET (or DELETE for one recording)")

  defp route(:GET, "/api/settings", arg), do: Settings.index(arg)

  defp route(_method, "/api/settings", _arg),
    do: not_allowed("GET (or GET, PUT, DELETE for one setting)")

  defp route(:GET, "/api/settings/" <> key, arg), do: Settings.show(arg, key)
  defp route(:PUT, "/api/settings/" <> key, arg), do: Settings.update(arg, key)
  defp route(:DELETE, "/api/settings/" <> key, arg), do: Settings.delete(arg, key)
  defp route(_method, "/api/settings/" <> _, _arg), do: not_allowed("GET, PUT or DELETE")
  defp route(:GET, "/api/snapshots", arg), do: Snapshots.index(arg)
  defp route(:GET, "/api/snapshots/" <> rest, arg), do: Snapshots.show(arg, parts(rest))
  defp route(_method, "/api/snapshots" <> _, _arg), do: not_allowed("GET")
  defp route(:POST, "/api/vehicles/" <> rest, arg), do: Snapshots.create(arg, parts(rest))
  defp route(_method, "/api/vehicles/" <> _, _arg), do: not_allowed("POST")
  defp route(_method, path, _arg), do: {404, %{error: "no such API endpoint: #{path}"}}

  defp parts(rest), do: String.split(rest, "/")

  defp not_allowed(methods), do: {405, %{error: "method not allowed: use #{methods}"}}
end
