defmodule NeptunusWeb.API do
  @moduledoc """
  The HTTP API under `/api` (a yaws appmod). JSON in, JSON out; errors are
  `{"error": reason}` with a 4xx status.

    * `GET /api/health` → `{"status": "ok", "version": v, "vehicles": [{"id", "board"}]}`
    * `POST /api/login` `{"name", "password"}` → `{"token", "expires_at", "user": {"name",
      "role"}}`; 400 in local mode or for a malformed body, 401 for a wrong name or password,
      403 for a foreign `Origin`, 429 (with `Retry-After`) after too many attempts from one
      address.
    * `GET /api/session` (token in `Authorization: Bearer …` or `?token=`) →
      `{"mode", "anonymous_observers", "user": {"name", "role"} | null, "expires_at"}`;
      401 with the same fields and `error` for an invalid or expired token.

  See `NeptunusWeb.Auth` and docs/API.md.
  """
  import NeptunusWeb.Yaws

  require Logger

  alias NeptunusWeb.{Auth, Socket}
  alias NeptunusWeb.Channels.Wire

  @max_body 4096

  @doc false
  def out(arg) do
    method = http_request(arg(arg, :req), :method)
    path = arg(arg, :server_path) |> to_string()
    respond(route(method, path, arg))
  rescue
    exception ->
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

  defp route(:GET, "/api/health", _arg), do: {200, health()}
  defp route(_method, "/api/health", _arg), do: {405, %{error: "method not allowed: use GET"}}
  defp route(:POST, "/api/login", arg), do: login(arg)
  defp route(_method, "/api/login", _arg), do: {405, %{error: "method not allowed: use POST"}}
  defp route(:GET, "/api/session", arg), do: session(arg)
  defp route(_method, "/api/session", _arg), do: {405, %{error: "method not allowed: use GET"}}
  defp route(_method, path, _arg), do: {404, %{error: "no such API endpoint: #{path}"}}

  defp login(arg) do
    headers = arg(arg, :headers)
    host = headers |> headers(:host) |> text()
    {address, _port} = arg(arg, :client_ip_port)

    with :ok <- Auth.check_origin(Socket.header(headers, "origin"), host, Auth.config().origins),
         {:ok, %{"name" => name, "password" => password}} <- body(arg),
         {:ok, session} <- Auth.login(name, password, address) do
      {200, session}
    else
      {:ok, _other} -> {400, %{error: "body must be {\"name\": …, \"password\": …}"}}
      {:error, 429, reason, retry_s} -> {429, %{error: reason}, [{"Retry-After", retry_s}]}
      {:error, status, reason} -> {status, %{error: reason}}
    end
  end

  defp session(arg) do
    token =
      case arg |> arg(:headers) |> headers(:authorization) do
        {_user, _password, ~c"Bearer " ++ token} -> token |> to_string() |> String.trim()
        _ -> query_token(arg)
      end

    case Auth.session(token) do
      {:ok, session} -> {200, session}
      {:error, session} -> {401, session}
    end
  end

  defp query_token(arg) do
    case arg(arg, :querydata) do
      :undefined -> nil
      query -> query |> to_string() |> URI.decode_query() |> Map.get("token")
    end
  rescue
    _ -> nil
  end

  defp body(arg) do
    case arg(arg, :clidata) do
      data when is_binary(data) and byte_size(data) <= @max_body ->
        try do
          {:ok, :jiffy.decode(data, [:return_maps])}
        catch
          _, _ -> {:error, 400, "body must be JSON: {\"name\": …, \"password\": …}"}
        end

      _ ->
        {:error, 400, "body missing or too large"}
    end
  end

  defp text(:undefined), do: nil
  defp text(value), do: to_string(value)

  defp respond({status, body}), do: respond({status, body, []})

  defp respond({status, body, headers}) do
    [
      {:status, status},
      {:header, {:cache_control, ~c"no-store"}}
      | Enum.map(headers, fn {name, value} ->
          {:header, {String.to_charlist(name), header_value(value)}}
        end)
    ] ++ [{:content, ~c"application/json", Wire.encode_json(body)}]
  end

  defp header_value(value) when is_integer(value), do: Integer.to_charlist(value)
  defp header_value(value), do: String.to_charlist(value)
end
