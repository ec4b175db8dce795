defmodule Neptunus.ConfigAuthTest do
  # Neptunus.Config.Auth, .TLS and .Helm: security and helm settings from the
  # environment (the doctests run in config_test.exs).
  use ExUnit.Case, async: true

  alias Neptunus.Config
  alias NeptunusWeb.Auth.Password

  @loopback %{bind: {127, 0, 0, 1}}
  @anywhere %{bind: {0, 0, 0, 0}}
  @secret String.duplicate("s", 32)

  setup_all do
    {:ok, hash: Password.hash("pw", iterations: 1000)}
  end

  describe "auth!/2" do
    test "loopback without secret or users: local mode", %{hash: _} do
      assert %{mode: :local, users: users, secret: nil} = Config.Auth.auth!(%{}, @loopback)
      assert users == %{}
      assert %{mode: :local} = Config.Auth.auth!(%{}, %{bind: {0, 0, 0, 0, 0, 0, 0, 1}})
    end

    test "any other address without a secret and users refuses, saying what to set" do
      for bind <- [{0, 0, 0, 0}, {192, 168, 0, 12}, {0, 0, 0, 0, 0, 0, 0, 0}] do
        error = assert_raise ArgumentError, fn -> Config.Auth.auth!(%{}, %{bind: bind}) end
        assert error.message =~ "NEPTUNUS_BIND=#{:inet.ntoa(bind)} serves beyond this computer"
        assert error.message =~ "Set NEPTUNUS_SECRET"
        assert error.message =~ "NEPTUNUS_USERS_FILE"
        assert error.message =~ "mix neptunus.passwd"
        assert error.message =~ "NEPTUNUS_BIND=127.0.0.1 for local mode"
      end
    end

    test "a secret and users: secure mode, on any address", %{hash: hash} do
      env = %{
        "NEPTUNUS_SECRET" => @secret,
        "NEPTUNUS_USERS" => "ada:pilot:#{hash}, main:main_station:#{hash},olga:observer:#{hash}",
        "NEPTUNUS_ANONYMOUS_OBSERVERS" => "true",
        "NEPTUNUS_ORIGINS" => "https://ROV.example.org/, http://10.0.0.2:4000",
        "NEPTUNUS_TOKEN_TTL_S" => "3600",
        "NEPTUNUS_LOGIN_ATTEMPTS" => "5"
      }

      for where <- [@anywhere, @loopback] do
        assert %{
                 mode: :secure,
                 secret: @secret,
                 users: %{"ada" => %{role: :pilot}, "main" => %{role: :main_station}} = users,
                 anonymous_observers: true,
                 origins: ["https://rov.example.org", "http://10.0.0.2:4000"],
                 token_ttl_s: 3600,
                 login_attempts_per_minute: 5
               } = Config.Auth.auth!(env, where)

        assert users["olga"] == %{name: "olga", role: :observer, hash: hash}
      end
    end

    @tag :tmp_dir
    @tag :capture_log
    test "users from a file, with comments and blank lines", %{hash: hash, tmp_dir: dir} do
      path = Path.join(dir, "users")
      File.write!(path, "# the crew\n\nada pilot #{hash}   # Ada\n  main  main_station #{hash}\n")
      env = %{"NEPTUNUS_SECRET" => @secret, "NEPTUNUS_USERS_FILE" => path}
      assert %{users: %{"ada" => _, "main" => _}} = Config.Auth.auth!(env, @anywhere)

      File.write!(path, "ada pilot #{hash}\nbob pilot\n")
      error = assert_raise ArgumentError, fn -> Config.Auth.auth!(env, @anywhere) end
      assert error.message =~ "#{path}, line 2"

      missing = %{env | "NEPTUNUS_USERS_FILE" => Path.join(dir, "nope")}

      assert_raise ArgumentError, ~r/NEPTUNUS_USERS_FILE=.*readable file/, fn ->
        Config.Auth.auth!(missing, @anywhere)
      end
    end

    @tag :tmp_dir
    test "a users file open to its group or others is used, with a warning at boot", %{
      hash: hash,
      tmp_dir: dir
    } do
      path = Path.join(dir, "users")
      File.write!(path, "ada pilot #{hash}\n")
      env = %{"NEPTUNUS_SECRET" => @secret, "NEPTUNUS_USERS_FILE" => path}

      File.chmod!(path, 0o644)

      log =
        ExUnit.CaptureLog.capture_log(fn ->
          assert %{users: %{"ada" => _}} = Config.Auth.auth!(env, @anywhere)
        end)

      assert log =~ "NEPTUNUS_USERS_FILE #{path} is open to others (mode 644)"
      assert log =~ "chmod 600 #{path}"

      File.chmod!(path, 0o640)
      log = ExUnit.CaptureLog.capture_log(fn -> Config.Auth.auth!(env, @anywhere) end)
      assert log =~ "is open to its group (mode 640)"

      File.chmod!(path, 0o600)

      # (other async tests may log meanwhile: only this file's warning is looked for)
      refute ExUnit.CaptureLog.capture_log(fn -> Config.Auth.auth!(env, @anywhere) end) =~
               "NEPTUNUS_USERS_FILE #{path}"
    end

    for {env, message} <- [
          {%{"NEPTUNUS_SECRET" => "short"}, ~r/NEPTUNUS_SECRET=.*at least 32 characters/},
          {%{"NEPTUNUS_SECRET" => String.duplicate("s", 32)}, ~r/no users/},
          {%{"NEPTUNUS_USERS" => "ada:pilot:HASH"}, ~r/NEPTUNUS_SECRET is not set/},
          {%{
             "NEPTUNUS_USERS" => "ada:captain:HASH",
             "NEPTUNUS_SECRET" => String.duplicate("s", 32)
           }, ~r/a role: pilot, observer or main_station/},
          {%{"NEPTUNUS_USERS" => "ada:pilot:md5", "NEPTUNUS_SECRET" => String.duplicate("s", 32)},
           ~r/password hash from `mix neptunus.passwd/},
          {%{
             "NEPTUNUS_USERS" => "a da:pilot:HASH",
             "NEPTUNUS_SECRET" => String.duplicate("s", 32)
           }, ~r/user names/},
          {%{"NEPTUNUS_USERS" => "ada:pilot", "NEPTUNUS_SECRET" => String.duplicate("s", 32)},
           ~r/name:role:hash entries/},
          {%{
             "NEPTUNUS_USERS" => "ada:pilot:HASH,ada:observer:HASH",
             "NEPTUNUS_SECRET" => String.duplicate("s", 32)
           }, ~r/unique user names/},
          {%{
             "NEPTUNUS_USERS" => "m1:main_station:HASH,m2:main_station:HASH",
             "NEPTUNUS_SECRET" => String.duplicate("s", 32)
           }, ~r/at most one main_station/},
          {%{"NEPTUNUS_ORIGINS" => "rov.example.org"}, ~r/NEPTUNUS_ORIGINS=.*origins like/},
          {%{"NEPTUNUS_ORIGINS" => "https://x.org/path"}, ~r/NEPTUNUS_ORIGINS/},
          {%{"NEPTUNUS_ANONYMOUS_OBSERVERS" => "maybe"}, ~r/true or false/},
          {%{"NEPTUNUS_TOKEN_TTL_S" => "10"}, ~r/NEPTUNUS_TOKEN_TTL_S="10".*60\.\.2592000/},
          {%{"NEPTUNUS_LOGIN_ATTEMPTS" => "x"}, ~r/NEPTUNUS_LOGIN_ATTEMPTS/}
        ] do
      test "refuses #{inspect(env)}", %{hash: hash} do
        env =
          Map.new(unquote(Macro.escape(env)), fn {k, v} ->
            {k, String.replace(v, "HASH", hash)}
          end)

        assert_raise ArgumentError, unquote(Macro.escape(message)), fn ->
          Config.Auth.auth!(env, @loopback)
        end
      end
    end
  end

  describe "tls!/1" do
    @tag :tmp_dir
    test "both files or neither", %{tmp_dir: dir} do
      cert = Path.join(dir, "cert.pem")
      key = Path.join(dir, "key.pem")
      File.write!(cert, "")
      File.write!(key, "")

      assert %{certfile: ^cert, keyfile: ^key} =
               Config.TLS.tls!(%{"NEPTUNUS_TLS_CERT" => cert, "NEPTUNUS_TLS_KEY" => key})

      assert_raise ArgumentError, ~r/NEPTUNUS_TLS_KEY.*private key/, fn ->
        Config.TLS.tls!(%{"NEPTUNUS_TLS_CERT" => cert})
      end

      assert_raise ArgumentError, ~r/NEPTUNUS_TLS_CERT.*certificate/, fn ->
        Config.TLS.tls!(%{"NEPTUNUS_TLS_KEY" => key})
      end

      assert_raise ArgumentError, ~r/NEPTUNUS_TLS_KEY=.*no such file/, fn ->
        Config.TLS.tls!(%{"NEPTUNUS_TLS_CERT" => cert, "NEPTUNUS_TLS_KEY" => key <> ".missing"})
      end
    end
  end

  describe "helm!/1" do
    test "values and ranges" do
      assert [deadman_ms: 250, request_timeout_ms: 5000, takeover_ms: 0] =
               Config.Helm.helm!(%{
                 "NEPTUNUS_DEADMAN_MS" => "250",
                 "NEPTUNUS_REQUEST_TIMEOUT_MS" => "5000",
                 "NEPTUNUS_TAKEOVER_MS" => "0"
               })

      assert_raise ArgumentError, ~r/NEPTUNUS_DEADMAN_MS="50".*100\.\.10000/, fn ->
        Config.Helm.helm!(%{"NEPTUNUS_DEADMAN_MS" => "50"})
      end
    end
  end
end
