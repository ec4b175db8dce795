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
  Spends the time of one verification of `iterations` (default: the default's) without a
  hash to compare against; `check/3` uses it to make every login cost the same.
  """
  @spec dummy_verify(String.t(), pos_integer()) :: false
  def dummy_verify(password, iterations \\ @default_iterations) when is_binary(password) do
    _ = derive(password, <<0::size(@salt_bytes * 8)>>, iterations)
    false
  end

  @doc "The iteration count of new hashes."
  @spec default_iterations() :: pos_integer()
  def default_iterations, do: @default_iterations

  @doc """
  The iteration count stored in `hash`, or nil for a malformed hash.

      iex> NeptunusWeb.Auth.Password.iterations(NeptunusWeb.Auth.Password.hash("x", iterations: 1000))
      1000
  """
  @spec iterations(String.t()) :: pos_integer() | nil
  def iterations(hash) do
    case parse(hash) do
      {:ok, %{iterations: n}} -> n
      {:error, _} -> nil
    end
  end

  @doc """
  The PBKDF2 derivations (their iteration counts, in order) that `check/3` runs for `hash`
  (nil: no such user) so that it costs `target` iterations in all: the hash's own, topped
  up to `target` by a derivation whose result is thrown away; `target` alone without a
  usable hash. A user whose hash is cheaper than `target` then takes exactly as long as a
  name that does not exist, and the time of a login tells nothing about which names exist.

      iex> NeptunusWeb.Auth.Password.plan(nil, 5000)
      [5000]
  """
  @spec plan(String.t() | nil, pos_integer()) :: [pos_integer()]
  def plan(hash, target) do
    case hash && iterations(hash) do
      nil -> [target]
      n when n >= target -> [n]
      n -> [n, target - n]
    end
  end

  @doc """
  Whether `password` matches `hash` (nil: no such user — never), spending the derivations
  of `plan(hash, target)` whatever the answer.
  """
  @spec check(String.t(), String.t() | nil, pos_integer()) :: boolean()
  def check(password, hash, target) when is_binary(password) do
    case {hash && iterations(hash), plan(hash, target)} do
      {nil, [n]} ->
        dummy_verify(password, n)

      {n, [n]} ->
        verify(password, hash)

      {n, [n, pad]} ->
        ok? = verify(password, hash)
        _ = dummy_verify(password, pad)
        ok?
    end
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
