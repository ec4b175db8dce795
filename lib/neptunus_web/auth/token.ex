defmodule NeptunusWeb.Auth.Token do
  @moduledoc """
  Signed, expiring login tokens:

      v1.PAYLOAD.SIGNATURE

  `PAYLOAD` is the unpadded URL-safe Base64 of the JSON `{"sub": user name, "iat": issued,
  "exp": expires}` (Unix seconds); `SIGNATURE` is the unpadded URL-safe Base64 of
  HMAC-SHA256 over `"v1." <> PAYLOAD`, keyed with a key derived from the configured secret
  (`NEPTUNUS_SECRET`). The token names the user only: the role is looked up in the current
  users at every connection, so removing or demoting a user takes effect at their next
  connection, and changing the secret logs everybody out.

  The token is readable by its holder (it is signed, not encrypted) and contains nothing
  secret. It travels in the WebSocket URL's query string (`token=…`) because yaws has no
  WebSocket subprotocols; access logging is off.

      iex> token = NeptunusWeb.Auth.Token.sign("ada", "s3cret-s3cret-s3cret-s3cret-s3cret", 1_000, 60)
      iex> NeptunusWeb.Auth.Token.verify(token, "s3cret-s3cret-s3cret-s3cret-s3cret", 1_059)
      {:ok, %{name: "ada", issued_at: 1_000, expires_at: 1_060}}
      iex> NeptunusWeb.Auth.Token.verify(token, "s3cret-s3cret-s3cret-s3cret-s3cret", 1_060)
      {:error, "token expired"}
      iex> NeptunusWeb.Auth.Token.verify(token, "another-secret-another-secret-xx", 1_000)
      {:error, "invalid token"}
  """

  @version "v1"

  @type claims :: %{name: String.t(), issued_at: integer(), expires_at: integer()}

  @doc "A token for user `name`, issued at `now` (Unix s), valid for `ttl_s` seconds."
  @spec sign(String.t(), binary(), integer(), pos_integer()) :: String.t()
  def sign(name, secret, now, ttl_s) do
    payload =
      %{"sub" => name, "iat" => now, "exp" => now + ttl_s}
      |> Neptunus.JSON.encode!()
      |> b64()

    signed = @version <> "." <> payload
    signed <> "." <> b64(mac(secret, signed))
  end

  @doc """
  Checks the signature and expiry at `now` (Unix s). Errors: `"invalid token"` (malformed,
  wrong signature or wrong secret) and `"token expired"`. A token is exactly what `sign/4`
  makes: Base64 with padding (`=`, which the decoder would accept) is malformed, so one
  token has one spelling.
  """
  @spec verify(term(), binary(), integer()) :: {:ok, claims()} | {:error, String.t()}
  def verify(token, secret, now) when is_binary(token) and byte_size(token) < 2048 do
    with [@version, payload, signature] <- String.split(token, "."),
         false <- String.contains?(token, "="),
         {:ok, signature} <- Base.url_decode64(signature, padding: false),
         true <- :crypto.hash_equals(mac(secret, @version <> "." <> payload), pad(signature)),
         {:ok, json} <- Base.url_decode64(payload, padding: false),
         {:ok, %{"sub" => name, "iat" => iat, "exp" => exp}}
         when is_binary(name) and is_integer(iat) and is_integer(exp) <-
           Neptunus.JSON.decode(json) do
      if now < exp,
        do: {:ok, %{name: name, issued_at: iat, expires_at: exp}},
        else: {:error, "token expired"}
    else
      _ -> {:error, "invalid token"}
    end
  end

  def verify(_token, _secret, _now), do: {:error, "invalid token"}

  defp mac(secret, data) do
    key = :crypto.mac(:hmac, :sha256, secret, "neptunus login token " <> @version)
    :crypto.mac(:hmac, :sha256, key, data)
  end

  # hash_equals/2 needs equal sizes; a wrong-sized signature is simply wrong
  defp pad(signature) when byte_size(signature) == 32, do: signature
  defp pad(_signature), do: <<0::256>>

  defp b64(bytes), do: Base.url_encode64(bytes, padding: false)
end
