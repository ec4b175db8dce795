defmodule NeptunusWeb.API.Request do
  @moduledoc """
  What the API's resources read from a request (yaws' `#arg{}`) about who sent it: its login
  token, whether its `Origin` is allowed, and what that lets it do (`NeptunusWeb.Auth`).
  `NeptunusWeb.CameraStream` asks the same of its requests.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias NeptunusWeb.Auth

  @doc "The login token of the request: `Authorization: Bearer …`, else `?token=`; nil: none."
  @spec token(tuple()) :: String.t() | nil
  def token(arg) do
    case arg |> arg(:headers) |> headers(:authorization) do
      {_user, _password, ~c"Bearer " ++ token} -> token |> to_string() |> String.trim()
      _ -> Map.get(query(arg), "token")
    end
  end

  @doc """
  Whether the request's `Origin` (none: not a browser) may send it: the configured origins,
  or the server's own (`NeptunusWeb.Auth.check_origin/3`); a foreign one is refused with 403.
  """
  @spec check_origin(tuple()) :: :ok | {:error, 403, String.t()}
  def check_origin(arg) do
    headers = arg(arg, :headers)
    host = headers |> headers(:host) |> text()
    Auth.check_origin(header(headers, "origin"), host, Auth.config().origins)
  end

  @doc """
  The request's body decoded as JSON, if it is at most `max_bytes` long: `{:error,
  :too_large}` for a longer (or a missing) body, whose rest yaws has not read;
  `{:error, {:json, reason}}` for a body that is not JSON.
  """
  @spec json_body(tuple(), pos_integer()) ::
          {:ok, term()} | {:error, :too_large | {:json, String.t()}}
  def json_body(arg, max_bytes) do
    case arg(arg, :clidata) do
      data when is_binary(data) and byte_size(data) <= max_bytes ->
        case Neptunus.JSON.decode(data) do
          {:ok, json} -> {:ok, json}
          {:error, reason} -> {:error, {:json, reason}}
        end

      _ ->
        {:error, :too_large}
    end
  end

  @doc """
  Whether the request may see what observers see (recordings, the camera): local mode, a
  valid token (`Authorization: Bearer …` or `?token=`), or anonymous observers allowed.
  """
  @spec may_watch(tuple()) :: :ok | {:error, String.t()}
  def may_watch(arg) do
    case Auth.session(token(arg)) do
      {:ok, %{mode: "local"}} -> :ok
      {:ok, %{user: %{}}} -> :ok
      {:ok, %{anonymous_observers: true}} -> :ok
      {:ok, _} -> {:error, "log in to see recordings and the camera"}
      {:error, %{error: reason}} -> {:error, reason}
    end
  end

  @doc """
  `fun`'s answer when the request may watch (`may_watch/1`); 401 with the reason otherwise.
  """
  @spec watching(tuple(), (() -> NeptunusWeb.API.Response.t())) :: NeptunusWeb.API.Response.t()
  def watching(arg, fun) do
    case may_watch(arg) do
      :ok -> fun.()
      {:error, reason} -> {401, %{error: reason}}
    end
  end

  @doc """
  The session of a request whose `Origin` is checked first (`check_origin/1`, then
  `NeptunusWeb.Auth.session/1`), for a request that changes something: `{:ok, session}`, or
  the HTTP status and body to refuse it with — 403 for a foreign `Origin`, 401 for a token
  that is not valid. What the session may do is the caller's to say.
  """
  @spec checked_session(tuple()) :: {:ok, map()} | {401 | 403, map()}
  def checked_session(arg) do
    with {:origin, :ok} <- {:origin, check_origin(arg)},
         {:ok, session} <- Auth.session(token(arg)) do
      {:ok, session}
    else
      {:origin, {:error, status, reason}} -> {status, %{error: reason}}
      {:error, %{error: reason}} -> {401, %{error: reason}}
    end
  end

  @doc """
  Whose settings a request reads and writes (`Neptunus.Settings`): in local mode the node's
  one user `{:user, "local"}`; in secure mode the token's user (any role); otherwise the
  HTTP status and reason to refuse with (401). A foreign `Origin` is refused (403).
  """
  @spec user_scope(tuple()) :: {:ok, Neptunus.Settings.scope()} | {401 | 403, map()}
  def user_scope(arg) do
    case checked_session(arg) do
      {:ok, %{mode: "local"}} -> {:ok, {:user, Neptunus.Settings.local_user()}}
      {:ok, %{user: %{name: name}}} -> {:ok, {:user, name}}
      {:ok, _} -> {401, %{error: "log in to keep settings"}}
      refused -> refused
    end
  end
end
