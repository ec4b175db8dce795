defmodule NeptunusWeb.Endpoint.Guard do
  @moduledoc """
  What the endpoint checks and adds on every HTTP request, whatever serves it (yaws' static
  files, the API, the camera, the WebSocket upgrade).

    * **Host** (yaws `arg_rewrite_mod`, `arg_rewrite/1`): a request whose `Host` is not
      allowed (`NeptunusWeb.Auth.check_host/2`: loopback only in local mode, the configured
      origins' hosts in secure mode) is answered `403 {"error": reason}` before anything
      runs, so a DNS-rebound name cannot list, export or delete recordings, read the
      pages or watch the camera through the operator's browser.
    * **Response headers** (yaws `extra_response_headers` `extramod`,
      `extra_response_headers/3`): every response gets `X-Content-Type-Options: nosniff`
      and `Referrer-Policy: no-referrer` (a login token may be in a URL); HTML gets
      `Content-Security-Policy` (`csp/0`: scripts, styles and connections from this origin
      only, never framed) and `X-Frame-Options: DENY` (the same for older browsers), so no
      other site can frame the operator page and trick a pilot into clicking.
  """
  import NeptunusWeb.Endpoint.Yaws

  alias Neptunus.JSON
  alias NeptunusWeb.Auth

  @csp Enum.join(
         [
           "default-src 'self'",
           "script-src 'self'",
           "style-src 'self'",
           "img-src 'self' data: blob:",
           "connect-src 'self'",
           "object-src 'none'",
           "base-uri 'none'",
           "form-action 'self'",
           "frame-ancestors 'none'"
         ],
         "; "
       )

  @doc "The `Content-Security-Policy` of the pages."
  @spec csp() :: String.t()
  def csp, do: @csp

  @doc false
  # yaws arg_rewrite_mod: every request passes here first
  def arg_rewrite(arg) do
    host =
      case headers(arg(arg, :headers), :host) do
        :undefined -> nil
        value -> to_string(value)
      end

    case Auth.check_host(Auth.config(), host) do
      :ok ->
        arg

      {:error, status, reason} ->
        body = IO.iodata_to_binary(JSON.encode!(%{error: reason}))

        response =
          rewrite_response(
            status: status,
            headers: [
              {:header, {:content_type, ~c"application/json"}},
              {:header, {:cache_control, ~c"no-store"}}
            ],
            content: body
          )

        arg(arg, state: response)
    end
  end

  @doc """
  The security headers for a response whose `Content-Type` is `content_type` (nil: none),
  as `{name, value}` pairs.

      iex> alias NeptunusWeb.Endpoint.Guard
      iex> Guard.headers_for("text/html") |> Map.new() |> Map.take(["X-Frame-Options"])
      %{"X-Frame-Options" => "DENY"}
      iex> Guard.headers_for("application/json")
      [{"X-Content-Type-Options", "nosniff"}, {"Referrer-Policy", "no-referrer"}]
  """
  @spec headers_for(String.t() | nil) :: [{String.t(), String.t()}]
  def headers_for(content_type) do
    always = [{"X-Content-Type-Options", "nosniff"}, {"Referrer-Policy", "no-referrer"}]

    if html?(content_type),
      do: always ++ [{"Content-Security-Policy", @csp}, {"X-Frame-Options", "DENY"}],
      else: always
  end

  defp html?(nil), do: false
  defp html?(type), do: type |> String.downcase() |> String.starts_with?("text/html")

  @doc false
  # yaws extra_response_headers extramod: `headers` maps header names to values
  def extra_response_headers(headers, _arg, _status) do
    content_type =
      Enum.find_value(headers, fn {name, value} ->
        if String.downcase(to_string(name)) == "content-type", do: to_string(value)
      end)

    Enum.reduce(headers_for(content_type), headers, fn {name, value}, acc ->
      Map.put(acc, String.to_charlist(name), String.to_charlist(value))
    end)
  end
end
