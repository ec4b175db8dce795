defmodule NeptunusWeb.API.Settings do
  @moduledoc """
  The user's own settings (`Neptunus.Settings`; the gamepad mapping, the developer page's
  plots), for local mode (one user, `"local"`) or a token of any role (the token's user);
  401 otherwise (anonymous observers keep nothing). A request with an `Origin` of another
  site is refused (403), as for logins (`NeptunusWeb.API.Request.user_scope/1`):

    * `GET /api/settings` → `{"user": name, "settings": {key: value}}`
    * `GET /api/settings/<key>` → `{"key", "value"}`; 404 when none is stored
    * `PUT /api/settings/<key>` `{"value": v}` → `{"key", "value"}`; 400 for a bad key, value
      or body, 413 for a body over `max_settings_body/0` bytes, 500 when it cannot be written
      (the previous value stays)
    * `DELETE /api/settings/<key>` → `{"deleted": key}` (also when none was stored)
  """
  alias Neptunus.Settings.Rules
  alias NeptunusWeb.API.Request

  # the largest body yaws hands over whole (its partial_post_size): a value of
  # Neptunus.Settings.Rules.max_value_bytes/0 and its {"value": …} wrapper fit
  @max_settings_body 10_240

  @doc "The largest `PUT /api/settings/<key>` body accepted, in bytes."
  @spec max_settings_body() :: pos_integer()
  def max_settings_body, do: @max_settings_body

  @doc "`GET /api/settings`: every setting of the request's user."
  @spec index(tuple()) :: NeptunusWeb.API.Response.t()
  def index(arg),
    do: with_user(arg, &{200, %{user: elem(&1, 1), settings: Neptunus.Settings.all(&1)}})

  @doc "`GET /api/settings/<key>`: one setting of the request's user."
  @spec show(tuple(), String.t()) :: NeptunusWeb.API.Response.t()
  def show(arg, key) do
    with_user(arg, fn scope ->
      case Neptunus.Settings.get(scope, key) do
        {:ok, value} ->
          {200, %{key: key, value: value}}

        :error ->
          case Rules.key(key) do
            :ok -> {404, %{error: "no setting #{key}"}}
            {:error, reason} -> {400, %{error: reason}}
          end
      end
    end)
  end

  @doc "`PUT /api/settings/<key>` `{\"value\": v}`: stores one setting of the request's user."
  @spec update(tuple(), String.t()) :: NeptunusWeb.API.Response.t()
  def update(arg, key) do
    with_user(arg, fn scope ->
      with {:ok, value} <- setting_body(arg),
           do: stored(Neptunus.Settings.put(scope, key, value), %{key: key, value: value})
    end)
  end

  @doc "`DELETE /api/settings/<key>`: forgets one setting of the request's user."
  @spec delete(tuple(), String.t()) :: NeptunusWeb.API.Response.t()
  def delete(arg, key) do
    with_user(arg, &stored(Neptunus.Settings.delete(&1, key), %{deleted: key}))
  end

  defp with_user(arg, fun) do
    case Request.user_scope(arg) do
      {:ok, scope} -> fun.(scope)
      refused -> refused
    end
  end

  # a change stored (answer), or why not: the store could not write (500) or refused (400)
  defp stored(:ok, answer), do: {200, answer}
  defp stored({:error, "cannot " <> _ = reason}, _answer), do: {500, %{error: reason}}
  defp stored({:error, reason}, _answer), do: {400, %{error: reason}}

  defp setting_body(arg) do
    case Request.json_body(arg, @max_settings_body) do
      {:ok, %{"value" => value} = body} when map_size(body) == 1 ->
        {:ok, value}

      {:ok, _} ->
        {400, %{error: "body must be {\"value\": …}"}}

      {:error, {:json, reason}} ->
        {400, %{error: "body must be JSON {\"value\": …}: #{reason}"}}

      {:error, :too_large} ->
        # the rest of the body is not read: the connection cannot carry another request
        {413, %{error: "body must be at most #{@max_settings_body} bytes"},
         [{"Connection", "close"}]}
    end
  end
end
