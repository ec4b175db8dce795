defmodule Neptunus.Config.TLS do
  @moduledoc """
  HTTPS/WSS (`NeptunusWeb.Endpoint`): `NEPTUNUS_TLS_CERT` and `NEPTUNUS_TLS_KEY`, PEM files,
  both or neither (neither: plain HTTP).
  """

  alias Neptunus.Config

  @doc """
  TLS from `NEPTUNUS_TLS_CERT` and `NEPTUNUS_TLS_KEY` (PEM files, both or neither): nil or
  `%{certfile, keyfile}`.

      iex> Neptunus.Config.TLS.tls!(%{})
      nil
  """
  @spec tls!(Config.env()) ::
          %{certfile: String.t(), keyfile: String.t()} | nil
  def tls!(env) do
    case {Map.get(env, "NEPTUNUS_TLS_CERT", ""), Map.get(env, "NEPTUNUS_TLS_KEY", "")} do
      {"", ""} ->
        nil

      {cert, ""} ->
        Config.bad!(
          "NEPTUNUS_TLS_KEY",
          "",
          "the private key (PEM) that goes with NEPTUNUS_TLS_CERT=#{cert}"
        )

      {"", key} ->
        Config.bad!(
          "NEPTUNUS_TLS_CERT",
          "",
          "the certificate (PEM) that goes with NEPTUNUS_TLS_KEY=#{key}"
        )

      {cert, key} ->
        for {variable, path} <- [{"NEPTUNUS_TLS_CERT", cert}, {"NEPTUNUS_TLS_KEY", key}],
            not File.regular?(path),
            do: Config.bad!(variable, path, "a readable PEM file (no such file)")

        %{certfile: Path.expand(cert), keyfile: Path.expand(key)}
    end
  end
end
