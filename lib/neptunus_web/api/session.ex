defmodule NeptunusWeb.API.Session do
  @moduledoc """
  `GET /api/session` (token in `Authorization: Bearer …` or `?token=`) → `{"mode",
  "anonymous_observers", "user": {"name", "role"} | null, "expires_at"}`
  (`NeptunusWeb.Auth.session/1`); 401 with the same fields and `error` for an invalid or
  expired token.
  """
  alias NeptunusWeb.API.Request
  alias NeptunusWeb.Auth

  @doc "Who the request's token is for, and the node's mode (see the moduledoc)."
  @spec show(tuple()) :: {200 | 401, map()}
  def show(arg) do
    case Auth.session(Request.token(arg)) do
      {:ok, session} -> {200, session}
      {:error, session} -> {401, session}
    end
  end
end
