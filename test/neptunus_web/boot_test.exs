defmodule NeptunusWeb.BootTest do
  # Boots the node as an operator would (`mix run`, in a separate OS process, the compiled
  # code of this test run) with the environment under test: secure by default, and TLS.
  use ExUnit.Case, async: false

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  alias NeptunusWeb.Auth.Password

  @moduletag :boot
  @moduletag timeout: 120_000
  @root Path.expand("../..", __DIR__)

  # Runs `mix run --no-compile -e script` with `env` on top of ours (nil unsets).
  defp boot(env, script) do
    mix = System.find_executable("mix") || flunk("mix not found")

    clean =
      for var <-
            ~w(NEPTUNUS_SECRET NEPTUNUS_USERS NEPTUNUS_USERS_FILE NEPTUNUS_BIND
                    NEPTUNUS_TLS_CERT NEPTUNUS_TLS_KEY NEPTUNUS_ANONYMOUS_OBSERVERS NEPTUNUS_ORIGINS),
          do: {var, nil}

    env = clean ++ [{"MIX_ENV", "test"}, {"NEPTUNUS_PORT", to_string(free_port())}] ++ env

    System.cmd(mix, ["run", "--no-compile", "-e", script],
      cd: @root,
      env: env,
      stderr_to_stdout: true
    )
  end

  @tag :tmp_dir
  test "bound beyond loopback without a secret and users, the node refuses to start", ctx do
    {output, status} = boot([{"NEPTUNUS_BIND", "0.0.0.0"}], ~S|IO.puts("STARTED")|)
    assert status != 0
    refute output =~ "STARTED"
    assert output =~ "NEPTUNUS_BIND=0.0.0.0 serves beyond this computer"
    assert output =~ "Set NEPTUNUS_SECRET"
    assert output =~ "NEPTUNUS_USERS_FILE"

    # a secret alone is not enough either
    {output, status} =
      boot(
        [{"NEPTUNUS_BIND", "0.0.0.0"}, {"NEPTUNUS_SECRET", String.duplicate("s", 40)}],
        ~S|IO.puts("STARTED")|
      )

    assert status != 0
    assert output =~ "NEPTUNUS_SECRET is set but there are no users"

    # bad users file lines are named
    users = Path.join(ctx.tmp_dir, "users")
    File.write!(users, "ada pilot not-a-hash\n")

    {output, status} =
      boot(
        [{"NEPTUNUS_SECRET", String.duplicate("s", 40)}, {"NEPTUNUS_USERS_FILE", users}],
        ~S|IO.puts("STARTED")|
      )

    assert status != 0
    assert output =~ "#{users}, line 1"
  end

  @tag :tmp_dir
  test "with a secret, users and a certificate it serves HTTPS and logs users in", ctx do
    %{server_config: server} =
      :public_key.pkix_test_data(%{
        server_chain: %{
          root: [key: {:rsa, 2048, 65537}],
          intermediates: [],
          peer: [key: {:rsa, 2048, 65537}]
        },
        client_chain: %{
          root: [key: {:rsa, 2048, 65537}],
          intermediates: [],
          peer: [key: {:rsa, 2048, 65537}]
        }
      })

    cert = Path.join(ctx.tmp_dir, "cert.pem")
    key = Path.join(ctx.tmp_dir, "key.pem")
    File.write!(cert, :public_key.pem_encode([{:Certificate, server[:cert], :not_encrypted}]))
    {key_type, key_der} = server[:key]
    File.write!(key, :public_key.pem_encode([{key_type, key_der, :not_encrypted}]))

    users = Path.join(ctx.tmp_dir, "users")

    File.write!(users, """
    # name  role          hash
    ada     pilot         #{Password.hash("ada pw", iterations: 1000)}
    main    main_station  #{Password.hash("main pw", iterations: 1000)}
    """)

    script = ~S"""
    {:ok, _} = Application.ensure_all_started(:inets)
    url = NeptunusWeb.Endpoint.url()
    IO.puts("URL " <> url)
    ssl = [ssl: [verify: :verify_none]]
    {:ok, {{_, health, _}, _, _}} = :httpc.request(:get, {~c"#{url}/api/health", []}, ssl, [])
    IO.puts("HEALTH #{health}")
    body = ~s({"name": "ada", "password": "ada pw"})
    {:ok, {{_, login, _}, _, json}} =
      :httpc.request(:post, {~c"#{url}/api/login", [], ~c"application/json", body}, ssl, [])
    IO.puts("LOGIN #{login} #{json}")
    plain = String.replace(url, "https:", "http:")
    IO.puts("PLAIN #{inspect(:httpc.request(:get, {~c"#{plain}/api/health", []}, [timeout: 2000], []) |> elem(0))}")
    # a wss connection gets the slow-client socket options too
    token = json |> to_string() |> :jiffy.decode([:return_maps]) |> Map.fetch!("token")
    port = Application.fetch_env!(:neptunus, :endpoint).port
    {:ok, s} = :ssl.connect(~c"127.0.0.1", port, [:binary, active: false, verify: :verify_none])
    key = Base.encode64(:crypto.strong_rand_bytes(16))
    :ok = :ssl.send(s, "GET /socket/websocket?vsn=2.0.0&token=#{URI.encode_www_form(token)} HTTP/1.1\r\nHost: 127.0.0.1:#{port}\r\n" <>
      "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: #{key}\r\n" <>
      "Sec-WebSocket-Version: 13\r\n\r\n")
    {:ok, "HTTP/1.1 101" <> _} = :ssl.recv(s, 0, 5_000)
    join = ~s(["1","1","fleet","phx_join",{}])
    :ok = :ssl.send(s, <<0x81, 0x80 + byte_size(join), 0::32, join::binary>>)
    {:ok, _reply} = :ssl.recv(s, 0, 5_000)
    [conn] = :pg.get_local_members(Neptunus.PubSub, {:fastlane, "fleet"})
    {:ssl, sock} = Enum.find_value(Tuple.to_list(:sys.get_state(conn)), fn
      {:ws_state, _, sock, _} -> sock
      _ -> nil
    end)
    {:ok, [{:raw, 6, 25, <<lowat::native-32>>}]} = :ssl.getopts(sock, [{:raw, 6, 25, 4}])
    {:ok, opts} = :ssl.getopts(sock, [:send_timeout, :send_timeout_close])
    IO.puts("WSS lowat=#{lowat} send_timeout=#{opts[:send_timeout]} close=#{opts[:send_timeout_close]}")
    """

    {output, status} =
      boot(
        [
          {"NEPTUNUS_SECRET", String.duplicate("s", 40)},
          {"NEPTUNUS_USERS_FILE", users},
          {"NEPTUNUS_TLS_CERT", cert},
          {"NEPTUNUS_TLS_KEY", key}
        ],
        script
      )

    assert status == 0, output
    assert output =~ ~r/URL https:\/\/127\.0\.0\.1:\d+/
    assert output =~ "HEALTH 200"
    assert output =~ ~r/LOGIN 200 .*"token":"v1\./
    assert output =~ ~r/"role":"pilot"/
    # the TLS port does not speak plain HTTP
    refute output =~ "PLAIN :ok"
    # a slow or frozen wss client is handled like a plain one (NeptunusWeb.Socket)
    # (the node runs with MIX_ENV=test, as this test does: the same config)
    timeout = NeptunusWeb.Endpoint.send_timeout_ms()
    assert output =~ "WSS lowat=4096 send_timeout=#{timeout} close=true"
  end
end
