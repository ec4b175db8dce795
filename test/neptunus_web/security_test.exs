defmodule NeptunusWeb.SecurityTest do
  # Upgrades, tokens and logins against the running endpoint. Secure mode is switched on at
  # run time (NeptunusWeb.Auth reads its configuration at every connection and login) and
  # restored after each test.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire

  alias NeptunusWeb.Auth.{Password, RateLimit, Token}
  alias NeptunusWeb.Test.WSClient

  @moduletag :capture_log
  @secret "security-test-secret-" <> String.duplicate("x", 20)

  setup do
    RateLimit.reset()
    :ok
  end

  defp secure!(overrides \\ %{}) do
    hash = Password.hash("ada's password", iterations: 1000)

    users = %{
      "ada" => %{name: "ada", role: :pilot, hash: hash},
      "main" => %{
        name: "main",
        role: :main_station,
        hash: Password.hash("main pw", iterations: 1000)
      },
      "olga" => %{name: "olga", role: :observer, hash: hash}
    }

    NeptunusWeb.Test.Wire.secure!(@secret, users, overrides)
  end

  defp token(name, issued_ago_s \\ 0, ttl_s \\ 600),
    do: Token.sign(name, @secret, System.os_time(:second) - issued_ago_s, ttl_s)

  defp refused(result) do
    assert {:error, {:http_status, status, %{body: body, headers: headers}}} = result
    assert {"content-type", "application/json"} in headers
    {status, :jiffy.decode(body, [:return_maps])["error"]}
  end

  defp http(method, path, headers \\ [], body \\ nil) do
    url = ~c"http://127.0.0.1:#{port()}#{path}"

    request =
      case method do
        :get -> {url, headers}
        :post -> {url, headers, ~c"application/json", body || ""}
      end

    {:ok, {{_, status, _}, resp_headers, resp_body}} =
      :httpc.request(method, request, [], body_format: :binary)

    {status, resp_headers, :jiffy.decode(resp_body, [:return_maps, {:null_term, nil}])}
  end

  defp login(name, password, headers \\ []) do
    http(:post, "/api/login", headers, :jiffy.encode(%{name: name, password: password}))
  end

  describe "Origin (cross-site WebSocket hijacking)" do
    test "local mode: same origin is allowed, another site is refused with 403" do
      own = "http://127.0.0.1:#{port()}"
      assert {:ok, _} = connect(%{}, [{"Origin", own}])

      assert {403, "origin not allowed: http://evil.example"} =
               refused(connect(%{}, [{"Origin", "http://evil.example"}]))

      # same host, another port is another origin
      assert {403, _} = refused(connect(%{}, [{"Origin", "http://127.0.0.1:1"}]))
      assert {403, _} = refused(connect(%{}, [{"Origin", "null"}]))
    end

    test "local mode: a rebound DNS name is refused even from its own origin" do
      host = "rebind.example:#{port()}"

      assert {403, reason} = refused(connect(%{}, [{"Host", host}, {"Origin", "http://#{host}"}]))

      assert reason =~ "host not allowed in local mode"
      assert {:ok, _} = connect(%{}, [{"Host", "localhost:#{port()}"}])
    end

    test "configured origins replace the same-origin rule" do
      secure!(%{origins: ["https://rov.example.org"]})
      params = %{"token" => token("ada")}
      # (the Host must be one of the origins' hosts too: NeptunusWeb.Auth.check_host/2)
      host = {"Host", "rov.example.org"}
      assert {:ok, _} = connect(params, [{"Origin", "https://rov.example.org"}, host])

      assert {403, _} = refused(connect(params, [{"Origin", "http://127.0.0.1:#{port()}"}, host]))
    end
  end

  describe "tokens" do
    test "secure mode: a missing, bad, expired or foreign token is refused with 401 and why" do
      secure!()
      assert {401, reason} = refused(connect())
      assert reason =~ "login required"
      assert {401, "invalid token"} = refused(connect(%{"token" => "v1.abc.def"}))
      assert {401, "invalid token"} = refused(connect(%{"token" => token("ada") <> "x"}))
      assert {401, "token expired"} = refused(connect(%{"token" => token("ada", 700, 600)}))

      forged =
        Token.sign("ada", String.duplicate("other-secret", 3), System.os_time(:second), 600)

      assert {401, "invalid token"} = refused(connect(%{"token" => forged}))
      assert {401, "unknown user: mallory"} = refused(connect(%{"token" => token("mallory")}))
    end

    test "a valid token connects as the user, with the role from the users (not the token)" do
      secure!()
      ws = connect!(%{"token" => token("olga"), "name" => "someone else"})
      {jr, snapshot} = join!(ws, "vehicle:neptunus-1")
      assert %{"name" => "olga", "role" => "observer", "mode" => "secure"} = snapshot["session"]

      state = event!(ws, "presence_state")

      assert [%{"name" => "olga", "role" => "observer", "pilot" => false}] =
               state["olga"]["metas"]

      assert {"error", %{"reason" => "forbidden"}} =
               push_and_reply(ws, jr, "vehicle:neptunus-1", "request_control", %{})
    end

    test "anonymous observers, when allowed, watch and nothing more" do
      secure!(%{anonymous_observers: true})
      ws = connect!()
      {jr, snapshot} = join!(ws, "vehicle:neptunus-1")
      assert %{"role" => "observer", "name" => "guest-" <> _} = snapshot["session"]

      for event <- ~w(request_control take_control) do
        assert {"error", %{"reason" => "forbidden"}} =
                 push_and_reply(ws, jr, "vehicle:neptunus-1", event, %{})
      end

      # a bad token is still refused: anonymous means no token, not any token
      assert {401, "invalid token"} = refused(connect(%{"token" => "nonsense"}))
    end
  end

  describe "POST /api/login" do
    test "a right password gets a token that opens the socket" do
      secure!()

      assert {200, headers, %{"token" => t, "expires_at" => exp, "user" => user}} =
               login("ada", "ada's password")

      assert {~c"cache-control", ~c"no-store"} in headers
      assert user == %{"name" => "ada", "role" => "pilot"}
      assert exp > System.os_time(:millisecond)
      ws = connect!(%{"token" => t})
      {_, snapshot} = join!(ws, "fleet")
      assert %{"vehicles" => [_ | _]} = snapshot

      assert {200, _, %{"mode" => "secure", "user" => ^user}} =
               http(:get, "/api/session", [{~c"authorization", ~c"Bearer " ++ to_charlist(t)}])

      assert {200, _, %{"user" => ^user}} = http(:get, "/api/session?token=#{t}")
    end

    test "wrong password and unknown user get the same 401" do
      secure!()
      assert {401, _, %{"error" => "wrong name or password"}} = login("ada", "nope")
      assert {401, _, %{"error" => "wrong name or password"}} = login("mallory", "nope")
    end

    test "malformed bodies get 400 with a reason" do
      secure!()
      assert {400, _, %{"error" => e1}} = http(:post, "/api/login", [], "{nope")
      assert e1 =~ "JSON"
      assert {400, _, %{"error" => e2}} = http(:post, "/api/login", [], ~s({"user": "ada"}))
      assert e2 =~ "name"
      assert {405, _, _} = http(:get, "/api/login")
    end

    test "attempts are rate-limited per address (429 with Retry-After)" do
      secure!(%{login_attempts_per_minute: 3})
      for _ <- 1..3, do: assert({401, _, _} = login("ada", "guess"))
      assert {429, headers, %{"error" => reason}} = login("ada", "ada's password")
      assert reason =~ "too many login attempts"
      assert {~c"retry-after", retry} = List.keyfind(headers, ~c"retry-after", 0)
      assert List.to_integer(retry) in 1..20
    end

    test "a login from another site is refused" do
      secure!()

      assert {403, _, %{"error" => "origin not allowed: http://evil.example"}} =
               login("ada", "ada's password", [{~c"origin", ~c"http://evil.example"}])
    end

    test "local mode needs no login and says so" do
      assert {400, _, %{"error" => reason}} = login("ada", "x")
      assert reason =~ "local mode"

      assert {200, _, %{"mode" => "local", "user" => nil, "anonymous_observers" => false}} =
               http(:get, "/api/session")
    end

    test "GET /api/session with a bad token is 401 with the reason" do
      secure!()

      assert {401, _, %{"error" => "token expired", "mode" => "secure"}} =
               http(:get, "/api/session?token=#{token("ada", 700, 600)}")

      assert {200, _, %{"user" => nil, "mode" => "secure"}} = http(:get, "/api/session")
    end
  end

  test "a refused upgrade leaves the endpoint serving" do
    secure!()
    assert {401, _} = refused(connect())
    NeptunusWeb.Test.Wire.settings!(auth: %{mode: :local})
    ws = connect!()
    WSClient.push(ws, nil, "hb", "phoenix", "heartbeat", %{})
    assert [nil, "hb", "phoenix", "phx_reply", %{"status" => "ok"}] = WSClient.recv_frame(ws)
  end
end
