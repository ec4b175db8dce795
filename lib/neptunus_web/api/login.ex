defmodule NeptunusWeb.API.Login do
  @moduledoc """
  `POST /api/login` `{"name", "password"}` → `{"token", "expires_at", "user": {"name",
  "role"}}` (`NeptunusWeb.Auth.login/3`); 400 in local mode or for a malformed body, 401 for
  a wrong name or password, 403 for a foreign `Origin`, 429 (with `Retry-After`) after too
  many attempts from one address.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias NeptunusWeb.API.Request
  alias NeptunusWeb.Auth

  @max_body 4096

  @doc "Logs a user in (see the moduledoc)."
  @spec create(tuple()) :: NeptunusWeb.API.Response.t()
  def create(arg) do
    {address, _port} = arg(arg, :client_ip_port)

    with :ok <- Request.check_origin(arg),
         {:ok, %{"name" => name, "password" => password}} <- body(arg),
         {:ok, session} <- Auth.login(name, password, address) do
      {200, session}
    else
      {:ok, _other} -> {400, %{error: "body must be {\"name\": …, \"password\": …}"}}
      {:error, 429, reason, retry_s} -> {429, %{error: reason}, [{"Retry-After", retry_s}]}
      {:error, status, reason} -> {status, %{error: reason}}
    end
  end

  defp body(arg) do
    case Request.json_body(arg, @max_body) do
      {:ok, json} -> {:ok, json}
      {:error, {:json, _}} -> {:error, 400, "body must be JSON: {\"name\": …, \"password\": …}"}
      {:error, :too_large} -> {:error, 400, "body missing or too large"}
    end
  end
end
