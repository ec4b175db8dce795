defmodule NeptunusWeb.HardeningTest do
  # Host checks (DNS rebinding), security headers, the Origin's scheme, token padding and
  # login cost, against the running endpoint where it matters. The auth and recording
  # configuration is switched at run time and restored after each test.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire, only: [port: 0, connect: 2]

  alias NeptunusWeb.Auth
  alias NeptunusWeb.Auth.{Password, RateLimit, Token}

  @moduletag :capture_log
  @moduletag :tmp_dir
  @secret "hardening-test-secret-" <> String.duplicate("z", 20)
  @name "20260101-000000Z-1.log"

  doctest NeptunusWeb.Endpoint.Guard

  setup %{tmp_dir: dir} do
    NeptunusWeb.Test.Wire.settings!(recording_dir: dir)
    RateLimit.reset()
    vehicle = "host-#{System.unique_integer([:positive])}"
    File.mkdir_p!(Path.join(dir, vehicle))
    file = Path.join([dir, vehicle, @name])
    File.write!(file, "")
    {:ok, vehicle: vehicle, rec_file: file}
  end

  # A raw HTTP/1.1 request with exactly these headers; the connection is read to its end.
  defp request(method, path, headers) do
    {status, headers, body, socket} =
      NeptunusWeb.Test.Wire.raw_request(method, path, headers ++ [{"Connection", "close"}])

    body =
      case headers do
        %{"content-length" => length} -> read_body(socket, body, String.to_integer(length))
        _ -> body
      end

    :gen_tcp.close(socket)
    {status, headers, body}
  end

  defp read_body(_socket, body, length) when byte_size(body) >= length, do: body

  defp read_body(socket, body, length) do
    {:ok, data} = :gen_tcp.recv(socket, 0, Neptunus.Test.Patience.ms())
    read_body(socket, body <> data, length)
  end

  defp error(body), do: :jiffy.decode(body, [:return_maps])["error"]

  defp secure!(overrides) do
    users = %{"ada" => %{name: "ada", role: :pilot, hash: Password.hash("pw", iterations: 1000)}}
    NeptunusWeb.Test.Wire.secure!(@secret, users, overrides)
  end

  describe "Host (DNS rebinding)" do
    test "local mode: every kind of request with a foreign Host is refused with 403, and nothing changes",
         %{vehicle: vehicle, rec_file: file} do
      rebound = "rebind.attacker.example:#{port()}"

      for {method, path} <- [
            {"GET", "/"},
            {"GET", "/index.html"},
            {"GET", "/assets/app.css"},
            {"GET", "/api/health"},
            {"GET", "/api/session"},
            {"POST", "/api/login"},
            {"GET", "/api/recordings"},
            {"GET", "/api/recordings/#{vehicle}/#{@name}"},
            {"DELETE", "/api/recordings/#{vehicle}/#{@name}"},
            {"GET", "/camera/#{vehicle}.mjpg"},
            {"GET", "/socket/websocket?vsn=2.0.0"}
          ] do
        assert {403, headers, body} = request(method, path, [{"Host", rebound}]),
               "#{method} #{path}"

        assert headers["content-type"] == "application/json"

        assert error(body) ==
                 "host not allowed in local mode: #{rebound} (use 127.0.0.1 or localhost)"
      end

      assert File.exists?(file)
      assert {403, _, body} = request("GET", "/api/health", [])
      assert error(body) =~ "no Host header"
    end

    test "local mode: loopback names and addresses, with or without the port, are served",
         %{vehicle: vehicle} do
      for host <- [
            "127.0.0.1:#{port()}",
            "127.0.0.1",
            "localhost:#{port()}",
            "LOCALHOST",
            "127.1.2.3",
            "[::1]:#{port()}"
          ] do
        assert {200, _, body} =
                 request("GET", "/api/recordings?vehicle=#{vehicle}", [{"Host", host}]),
               host

        assert [%{"name" => @name}] = :jiffy.decode(body, [:return_maps])["recordings"]
      end

      assert {200, _, _} = request("GET", "/index.html", [{"Host", "localhost"}])
    end

    test "local mode: a DELETE with a loopback Host still works", %{
      vehicle: vehicle,
      rec_file: file
    } do
      assert {200, _, _} =
               request("DELETE", "/api/recordings/#{vehicle}/#{@name}", [{"Host", "127.0.0.1"}])

      refute File.exists?(file)
    end

    test "secure mode: only the configured origins' hosts, any port" do
      secure!(%{origins: ["https://rov.example.org", "http://10.0.0.2:4000"]})

      for host <- ["rov.example.org", "ROV.example.org:8443", "10.0.0.2:4000", "10.0.0.2"] do
        assert {200, _, _} = request("GET", "/api/health", [{"Host", host}]), host
      end

      assert {403, _, body} = request("GET", "/api/health", [{"Host", "rebind.attacker.example"}])

      assert error(body) ==
               "host not allowed: rebind.attacker.example (allowed: rov.example.org, 10.0.0.2)"
    end

    test "secure mode without configured origins: any host (tokens guard every request)" do
      secure!(%{})
      assert {200, _, _} = request("GET", "/api/health", [{"Host", "rov.anywhere.example"}])
    end
  end

  describe "security headers" do
    test "HTML pages: a Content-Security-Policy that forbids framing, X-Frame-Options DENY" do
      for page <- ["/", "/index.html", "/login.html", "/dev.html"] do
        assert {200, headers, _} = request("GET", page, [{"Host", "127.0.0.1"}])
        assert headers["content-type"] =~ "text/html", page
        assert headers["x-frame-options"] == "DENY", page
        assert headers["content-security-policy"] == NeptunusWeb.Endpoint.Guard.csp(), page
        assert headers["content-security-policy"] =~ "frame-ancestors 'none'"
        assert headers["content-security-policy"] =~ "script-src 'self';"
        assert headers["x-content-type-options"] == "nosniff", page
      end
    end

    test "other responses: nosniff, and no page policy where none is needed" do
      for path <- [
            "/api/health",
            "/assets/app.js",
            "/assets/app.css",
            "/api/nothing",
            "/nothing.html"
          ] do
        {_status, headers, _} = request("GET", path, [{"Host", "127.0.0.1"}])
        assert headers["x-content-type-options"] == "nosniff", path
        assert headers["referrer-policy"] == "no-referrer", path
      end
    end
  end

  describe "Origin scheme" do
    test "an http:// origin is not the same origin as an https server" do
      host = "rov.local:4000"
      assert Auth.check_origin("https://rov.local:4000", host, [], "https") == :ok
      assert {:error, 403, _} = Auth.check_origin("http://rov.local:4000", host, [], "https")
      assert {:error, 403, _} = Auth.check_origin("https://rov.local:4000", host, [], "http")
      assert Auth.check_origin("http://rov.local:4000", host, [], "http") == :ok
    end

    test "the running (plain http) endpoint refuses an https origin of its own host" do
      own = "https://127.0.0.1:#{port()}"
      assert {:error, {:http_status, 403, _}} = connect(%{}, [{"Origin", own}])
      assert {:ok, _} = connect(%{}, [{"Origin", "http://127.0.0.1:#{port()}"}])
    end
  end

  describe "tokens" do
    test "a signature with trailing '=' (padding) is refused" do
      token = Token.sign("ada", @secret, 1_000, 60)
      assert {:ok, _} = Token.verify(token, @secret, 1_001)
      assert {:error, "invalid token"} = Token.verify(token <> "=", @secret, 1_001)
      assert {:error, "invalid token"} = Token.verify(token <> "==", @secret, 1_001)
      [v, payload, sig] = String.split(token, ".")
      assert {:error, "invalid token"} = Token.verify("#{v}.#{payload}=.#{sig}", @secret, 1_001)
    end
  end

  describe "login cost" do
    defp users(iterations) do
      iterations
      |> Enum.with_index()
      |> Map.new(fn {n, i} ->
        name = "user#{i}"
        {name, %{name: name, role: :pilot, hash: Password.hash("pw", iterations: n)}}
      end)
    end

    test "an unknown name costs what the most expensive configured user costs" do
      assert Auth.login_iterations(%{users: users([1000])}) == 1000
      assert Auth.login_iterations(%{users: users([1000, 5000, 2000])}) == 5000
      # no users: the default of new hashes
      assert Auth.login_iterations(%{users: %{}}) == 200_000
    end

    test "every path of a login spends exactly that many iterations" do
      users = users([1000, 5000])
      target = Auth.login_iterations(%{users: users})

      assert Password.plan(nil, target) == [target]
      assert Password.plan(users["user0"].hash, target) == [1000, target - 1000]
      assert Password.plan(users["user1"].hash, target) == [5000]
      assert Password.plan("not a hash", target) == [target]

      for {_, %{hash: hash}} <- users do
        assert Password.plan(hash, target) |> Enum.sum() == target
      end

      # and the answers stay right
      assert Password.check("pw", users["user0"].hash, target)
      refute Password.check("wrong", users["user0"].hash, target)
      refute Password.check("pw", nil, target)
    end

    test "a login with an unknown name is refused like a wrong password" do
      secure!(%{})
      assert {:error, 401, "wrong name or password"} = Auth.login("nobody", "pw", {127, 0, 0, 1})
      assert {:error, 401, "wrong name or password"} = Auth.login("ada", "nope", {127, 0, 0, 1})
      assert {:ok, %{user: %{name: "ada"}}} = Auth.login("ada", "pw", {127, 0, 0, 1})
    end
  end
end
