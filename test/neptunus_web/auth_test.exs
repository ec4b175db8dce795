defmodule NeptunusWeb.AuthTest do
  use ExUnit.Case, async: true

  doctest NeptunusWeb.Auth.Password
  doctest NeptunusWeb.Auth.Token
  doctest NeptunusWeb.Auth.RateLimit
  doctest NeptunusWeb.Auth

  alias NeptunusWeb.Auth
  alias NeptunusWeb.Auth.{Password, RateLimit, Token}

  describe "Password" do
    test "salted: the same password hashes differently, and both verify" do
      a = Password.hash("secret", iterations: 1000)
      b = Password.hash("secret", iterations: 1000)
      refute a == b
      assert Password.verify("secret", a) and Password.verify("secret", b)
      assert "pbkdf2-sha256$1000$" <> _ = a
    end

    test "the iteration count travels with the hash" do
      hash = Password.hash("pw", iterations: 2000)
      assert {:ok, %{iterations: 2000, salt: salt, hash: h}} = Password.parse(hash)
      assert byte_size(salt) == 16 and byte_size(h) == 32
      assert :crypto.pbkdf2_hmac(:sha256, "pw", salt, 2000, 32) == h
    end

    test "malformed hashes never match" do
      for bad <- ["", "pbkdf2-sha256$10$abc$def", "pbkdf2-sha256$1000$!!$!!", "plain"] do
        refute Password.verify("pw", bad)
        assert {:error, _} = Password.parse(bad)
      end
    end

    test "hashes contain nothing that breaks a users file or NEPTUNUS_USERS" do
      for _ <- 1..20 do
        refute Password.hash("pw", iterations: 1000) =~ ~r/[\s:,#]/
      end
    end
  end

  describe "Token" do
    @secret String.duplicate("k", 32)

    test "tampering with the payload breaks the signature" do
      token = Token.sign("ada", @secret, 100, 60)
      ["v1", payload, sig] = String.split(token, ".")
      {:ok, json} = Base.url_decode64(payload, padding: false)
      forged = Base.url_encode64(String.replace(json, "ada", "eve"), padding: false)
      assert Token.verify("v1.#{forged}.#{sig}", @secret, 100) == {:error, "invalid token"}
    end

    test "garbage is invalid, never a crash" do
      for bad <- [nil, 42, "", "v1", "v1..", "v2.a.b", String.duplicate("a", 5000), "v1.e30.AAAA"] do
        assert Token.verify(bad, @secret, 0) == {:error, "invalid token"}
      end
    end
  end

  describe "RateLimit.take/3" do
    test "refills at capacity per minute, up to capacity" do
      {:ok, b} = RateLimit.take(nil, 0, 6)
      b = Enum.reduce(1..5, b, fn _, b -> elem(RateLimit.take(b, 0, 6), 1) end)
      assert {:error, 10_000} = RateLimit.take(b, 0, 6)
      assert {:ok, _} = RateLimit.take(b, 10_000, 6)
      # a long pause refills to capacity, not beyond
      {:ok, {tokens, _}} = RateLimit.take(b, 3_600_000, 6)
      assert tokens == 5.0
    end
  end

  describe "check_origin/3" do
    test "default ports and IPv6 hosts" do
      assert :ok = Auth.check_origin("http://localhost", "localhost", [])

      assert :ok =
               Auth.check_origin("https://rov.example.org", "rov.example.org:443", [], "https")

      assert :ok = Auth.check_origin("http://[::1]:4000", "[::1]:4000", [])

      assert {:error, 403, _} =
               Auth.check_origin("https://localhost:4000", "localhost:4000", ["http://x"])

      assert {:error, 403, _} = Auth.check_origin("http://localhost", nil, [])
      assert {:error, 403, _} = Auth.check_origin("ftp://localhost", "localhost", [])
    end

    test "configured origins compare case-insensitively and without a trailing slash" do
      assert :ok = Auth.check_origin("HTTPS://ROV.example.org", "h", ["https://rov.example.org/"])
    end
  end

  test "check_local_host/2 accepts loopback names only" do
    for ok <- [
          "localhost",
          "localhost:4000",
          "127.0.0.1:4000",
          "127.1.2.3",
          "[::1]:4000",
          "app.localhost"
        ] do
      assert :ok = Auth.check_local_host(:local, ok), ok
    end

    for bad <- ["10.0.0.2:4000", "example.org", "localhost.example.org", "[::2]:4000"] do
      assert {:error, 403, _} = Auth.check_local_host(:local, bad), bad
    end

    assert :ok = Auth.check_local_host(:secure, "example.org")
  end
end
