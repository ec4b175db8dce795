defmodule NeptunusWeb.EndpointLimitsTest do
  use ExUnit.Case, async: true

  alias NeptunusWeb.Endpoint

  doctest Endpoint

  describe "connection_limit/2" do
    test "derived: half of what the reserve leaves, the reserve at least 64 or 1/16" do
      assert Endpoint.connection_limit(nil, 256) == {96, :derived}
      assert Endpoint.connection_limit(nil, 1024) == {480, :derived}
      assert Endpoint.connection_limit(nil, 65_536) == {30_720, :derived}
      # never zero: a node with almost no descriptors still serves one connection
      assert Endpoint.connection_limit(nil, 10) == {1, :derived}
    end

    test "always below the descriptor limit, with room for a file per connection" do
      for limit <- [66, 100, 256, 1000, 1024, 4096, 20_000, 65_536, 1_048_576] do
        {connections, :derived} = Endpoint.connection_limit(nil, limit)
        assert 2 * connections + 64 <= limit
      end
    end

    test "a configured maximum is kept when the descriptors hold it, else lowered" do
      assert Endpoint.connection_limit(96, 256) == {96, :configured}
      assert Endpoint.connection_limit(1, 256) == {1, :configured}
      assert Endpoint.connection_limit(97, 256) == {96, {:lowered, 97}}
    end

    test "refuses nonsense" do
      assert_raise FunctionClauseError, fn -> Endpoint.connection_limit(0, 256) end
      assert_raise FunctionClauseError, fn -> Endpoint.connection_limit(nil, 0) end
      assert_raise FunctionClauseError, fn -> Endpoint.connection_limit(:all, 256) end
    end
  end

  test "the running endpoint serves at most its limit and reads heads for the header timeout" do
    {:ok, gconf, _} = :yaws_api.getconf()
    {limit, _} = Endpoint.connection_limit(nil, Neptunus.OS.socket_limit())
    # gconf: max_connections is field 13, keepalive_timeout field 8
    assert elem(gconf, 13) == limit
    assert elem(gconf, 8) == Endpoint.header_timeout_ms()
  end
end
