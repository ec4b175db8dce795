defmodule NeptunusWeb.Auth.Password do
  @moduledoc """
  Salted password hashes: PBKDF2-HMAC-SHA256 (`:crypto.pbkdf2_hmac/5`) in the text form

      pbkdf2-sha256$ITERATIONS$SALT$HASH

  with `SALT` (16 random bytes) and `HASH` (32 bytes) in unpadded URL-safe Base64, so a hash
  contains no `:`, `,`, `#` or whitespace and fits in a users file or an environment variable.
  The iteration count is stored in each hash: raising the default only affects new hashes.

  The default, #{200_000} iterations, takes ≈ 0.12 s on the 2-core development VM (and
  several times that on a BeagleBone Black); OWASP's 2023 figure for PBKDF2-SHA256 is 600 000.
  Logins are rare and rate-limited, so choose the highest count the vehicle's computer can
  spare (`mix neptunus.passwd --iterations N`).

      iex> hash = NeptunusWeb.Auth.Password.hash("correct horse", iterations: 1000)
      iex> NeptunusWeb.Auth.Password.verify("correct horse", hash)
      true
      iex> NeptunusWeb.Auth.Password.verify("wrong", hash)
      false
  """

  @default_iterations 200_000
  @salt_bytes 16
  @hash_bytes 32
  @prefix "pbkdf2-sha256"

  @typedoc "A parsed hash."
  @type parsed :: %{iterations: pos_integer(), salt: binary(), hash: binary()}

  @doc "Hashes `password` with a fresh random salt. Option: `:iterations`."
  @spec hash(String.t(), keyword()) :: String.t()
  def hash(password, opts \\ []) when is_binary(password) do
    iterations = Keyword.get(opts, :iterations, @default_iterations)
    salt = :crypto.strong_rand_bytes(@salt_bytes)
    derived = derive(password, salt, iterations)
    Enum.join([@prefix, iterations, b64(salt), b64(derived)], "$")
  end

  @doc """
  Whether `password` matches `hash` (constant-time comparison). A malformed hash never
  matches.
  """
  @spec verify(String.t(), String.t()) :: boolean()
  def verify(password, hash) when is_binary(password) and is_binary(hash) do
    case parse(hash) do
      {:ok, %{iterations: n, salt: salt, hash: expected}} ->
        :crypto.hash_equals(derive(password, salt, n), expected)

      {:error, _} ->
        false
    end
  end

  @doc """
  Spends the time of one verification without a hash to compare against, so a login for an
  unknown user takes as long as one with a wrong password.
  """
  @spec dummy_verify(String.t()) :: false
  def dummy_verify(password) when is_binary(password) do
    _ = derive(password, <<0::size(@salt_bytes * 8)>>, @default_iterations)
    false
  end

  @doc """
  Parses a hash's text form.

      iex> NeptunusWeb.Auth.Password.parse("md5$abc")
      {:error, "not a pbkdf2-sha256$ITERATIONS$SALT$HASH password hash"}
  """
  @spec parse(String.t()) :: {:ok, parsed()} | {:error, String.t()}
  def parse(text) when is_binary(text) do
    with [@prefix, iterations, salt, hash] <- String.split(text, "$"),
         {n, ""} when n in 1000..100_000_000 <- Integer.parse(iterations),
         {:ok, salt} when byte_size(salt) >= 8 <- Base.url_decode64(salt, padding: false),
         {:ok, hash} when byte_size(hash) == @hash_bytes <-
           Base.url_decode64(hash, padding: false) do
      {:ok, %{iterations: n, salt: salt, hash: hash}}
    else
      _ -> {:error, "not a #{@prefix}$ITERATIONS$SALT$HASH password hash"}
    end
  end

  defp derive(password, salt, iterations),
    do: :crypto.pbkdf2_hmac(:sha256, password, salt, iterations, @hash_bytes)

  defp b64(bytes), do: Base.url_encode64(bytes, padding: false)
end
