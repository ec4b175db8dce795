defmodule NeptunusWeb.WebSocket.TransportTest do
  # The socket under a WebSocket, on a plain TCP pair of this test. Through the endpoint
  # (yaws' sockets, TLS, the send timeout): test/neptunus_web/socket_test.exs.
  use ExUnit.Case, async: true

  alias NeptunusWeb.WebSocket.Transport

  setup do
    {:ok, listen} = :gen_tcp.listen(0, [:binary, active: false, ip: {127, 0, 0, 1}])
    {:ok, port} = :inet.port(listen)
    {:ok, client} = :gen_tcp.connect({127, 0, 0, 1}, port, [:binary, active: false])
    {:ok, server} = :gen_tcp.accept(listen, Neptunus.Test.Patience.ms())
    :gen_tcp.close(listen)
    on_exit(fn -> :gen_tcp.close(client) end)
    {:ok, server: server, client: client}
  end

  test "write/2 sends iodata as it is", %{server: server, client: client} do
    shared = "a payload shared by many"
    assert Transport.write(server, [<<0x81, byte_size(shared)>>, shared]) == :ok

    assert {:ok, <<0x81, 24, ^shared::binary>>} =
             :gen_tcp.recv(client, 26, Neptunus.Test.Patience.ms())
  end

  test "limit_unsent/2 sets TCP_NOTSENT_LOWAT on Linux; nil leaves the kernel's own", %{
    server: server
  } do
    before = :inet.getopts(server, [{:raw, 6, 25, 4}])
    assert Transport.limit_unsent(server, nil) == :ok
    assert :inet.getopts(server, [{:raw, 6, 25, 4}]) == before

    if :os.type() == {:unix, :linux} do
      assert Transport.limit_unsent(server, 8_192) == :ok

      assert {:ok, [{:raw, 6, 25, <<8_192::native-32>>}]} =
               :inet.getopts(server, [{:raw, 6, 25, 4}])
    end

    # a connection not open yet has no socket: nothing to set
    assert Transport.limit_unsent(nil, 4_096) == :ok
  end

  test "connected?/1 is true while the socket is open, false once it is closed", %{
    server: server
  } do
    assert Transport.connected?(server)
    :gen_tcp.close(server)
    refute Transport.connected?(server)
    # before the connection has a socket, yaws holds it
    assert Transport.connected?(nil)
  end
end
