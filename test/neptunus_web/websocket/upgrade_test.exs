defmodule NeptunusWeb.WebSocket.UpgradeTest do
  # The upgrade every WebSocket endpoint shares, on yaws' request records; the node under
  # test runs in local mode (loopback, no secret). The refusals over a real socket, in both
  # modes: test/neptunus_web/security_test.exs and hardening_test.exs.
  use ExUnit.Case, async: true

  import NeptunusWeb.Endpoint.Yaws

  alias NeptunusWeb.WebSocket.Upgrade

  defp request(host, query, other \\ []) do
    arg(headers: headers(host: host, other: other), querydata: query)
  end

  defp origin(value), do: [{:http_header, 0, ~c"Origin", :undefined, value}]

  test "a request the endpoint lets in runs the handler with its state and the user" do
    arg = request(~c"127.0.0.1:4000", ~c"vsn=2.0.0&name=ada", origin(~c"http://127.0.0.1:4000"))

    assert {:websocket, MyHandler, [{:callback, {:basic, state}}, hibernate_after: 1_000]} =
             Upgrade.upgrade(arg, MyHandler, %{vehicle: "rov-1"}, hibernate_after: 1_000)

    assert %{vehicle: "rov-1", user: %{name: "ada", role: :pilot, id: id}} = state
    assert is_binary(id)
    assert {:ok, %{name: "ada"}} = Upgrade.authorize(arg)
  end

  test "a foreign Origin or Host is refused with 403 and the reason, as JSON" do
    foreign_origin = request(~c"127.0.0.1:4000", :undefined, origin(~c"https://evil.example"))
    foreign_host = request(~c"rebind.example:4000", :undefined)

    for arg <- [foreign_origin, foreign_host] do
      assert {:error, 403, reason} = Upgrade.authorize(arg)

      assert [{:status, 403}, {:content, ~c"application/json", body}] =
               Upgrade.upgrade(arg, MyHandler)

      assert :jiffy.decode(body, [:return_maps]) == %{"error" => reason}
    end
  end

  test "refuse/2 answers a status with {\"error\": reason}" do
    assert [{:status, 404}, {:content, ~c"application/json", body}] =
             Upgrade.refuse(404, "no such socket endpoint: /x")

    assert :jiffy.decode(body, [:return_maps]) == %{"error" => "no such socket endpoint: /x"}
  end
end
