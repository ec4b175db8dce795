defmodule NeptunusWeb.API.SettingsTest do
  # /api/settings against the running endpoint and the node's settings store; each test uses
  # keys of its own and removes them, and restores the auth configuration.
  use ExUnit.Case, async: false

  import NeptunusWeb.Test.Wire, only: [secure!: 2, secure!: 3]

  alias Neptunus.Settings
  alias NeptunusWeb.Auth.Token

  @moduletag :capture_log
  @secret "settings-test-secret-" <> String.duplicate("z", 20)

  setup do
    auth = Application.get_env(:neptunus, :auth)
    key = "test.#{System.unique_integer([:positive])}"

    on_exit(fn ->
      Application.put_env(:neptunus, :auth, auth)

      for user <- ["local", "ada", "olga"],
          do: Settings.delete({:user, user}, key)
    end)

    {:ok, key: key}
  end

  defp port, do: Application.fetch_env!(:neptunus, :endpoint).port

  defp request(method, path, headers \\ [], body \\ nil) do
    url = ~c"http://127.0.0.1:#{port()}#{path}"

    req =
      if body,
        do: {url, headers, ~c"application/json", body},
        else: {url, headers}

    {:ok, {{_, status, _}, _headers, resp}} =
      :httpc.request(method, req, [], body_format: :binary)

    {status, :jiffy.decode(resp, [:return_maps, {:null_term, nil}])}
  end

  defp put(path, value, headers \\ []),
    do: request(:put, path, headers, Neptunus.JSON.encode!(%{value: value}))

  defp bearer(user) do
    token = Token.sign(user, @secret, System.os_time(:second), 600)
    [{~c"authorization", ~c"Bearer " ++ String.to_charlist(token)}]
  end

  test "local mode: one user, \"local\"; put, get, list, delete", %{key: key} do
    value = %{"buttons" => %{"0" => "stop", "9" => "request_control"}, "repeat_ms" => 250}
    assert {404, %{"error" => "no setting " <> _}} = request(:get, "/api/settings/#{key}")

    assert {200, %{"key" => ^key, "value" => ^value}} = put("/api/settings/#{key}", value)
    assert {200, %{"key" => ^key, "value" => ^value}} = request(:get, "/api/settings/#{key}")
    assert {200, %{"user" => "local", "settings" => all}} = request(:get, "/api/settings")
    assert all[key] == value
    assert Settings.get({:user, "local"}, key) == {:ok, value}

    assert {200, %{"deleted" => ^key}} = request(:delete, "/api/settings/#{key}")
    assert {404, _} = request(:get, "/api/settings/#{key}")
    assert {200, %{"deleted" => ^key}} = request(:delete, "/api/settings/#{key}")
  end

  test "bad keys, values and bodies are refused and change nothing", %{key: key} do
    assert {200, _} = put("/api/settings/#{key}", 1)

    assert {400, %{"error" => "a key must be" <> _}} = put("/api/settings/a%2Fb", 1)
    assert {400, %{"error" => "a key must be" <> _}} = request(:get, "/api/settings/a%20b")
    assert {400, %{"error" => "a key must be" <> _}} = request(:delete, "/api/settings/")

    assert {400, %{"error" => "body must be {\"value\": …}"}} =
             request(:put, "/api/settings/#{key}", [], ~s({"v": 2}))

    assert {400, %{"error" => "body must be JSON" <> _}} =
             request(:put, "/api/settings/#{key}", [], ~s({"value": ))

    too_long = String.duplicate("x", Settings.Rules.max_value_bytes())

    assert {400, %{"error" => "a value must be at most 8192 bytes" <> _}} =
             put("/api/settings/#{key}", too_long)

    huge = String.duplicate("x", NeptunusWeb.API.Settings.max_settings_body())

    assert {413, %{"error" => "body must be at most 10240 bytes"}} =
             put("/api/settings/#{key}", huge)

    assert {200, %{"value" => 1}} = request(:get, "/api/settings/#{key}")

    assert {405, _} = request(:post, "/api/settings/#{key}", [], "{}")
    assert {405, _} = request(:delete, "/api/settings")
  end

  test "a value as large as the store allows goes through one body", %{key: key} do
    largest = String.duplicate("x", Settings.Rules.max_value_bytes() - 2)
    assert {200, _} = put("/api/settings/#{key}", largest)
    assert {200, %{"value" => ^largest}} = request(:get, "/api/settings/#{key}")
  end

  test "a page of another site may not read or write settings", %{key: key} do
    evil = [{~c"origin", ~c"http://evil.example"}]
    assert {403, %{"error" => "origin not allowed: " <> _}} = put("/api/settings/#{key}", 1, evil)
    assert {403, _} = request(:get, "/api/settings", evil)
    assert Settings.get({:user, "local"}, key) == :error

    own = [{~c"origin", String.to_charlist("http://127.0.0.1:#{port()}")}]
    assert {200, _} = put("/api/settings/#{key}", 1, own)
  end

  test "secure mode: each user their own settings; no token, no settings", %{key: key} do
    users = %{
      "olga" => %{name: "olga", role: :observer, hash: "unused"},
      "ada" => %{name: "ada", role: :pilot, hash: "unused"}
    }

    secure!(@secret, users, %{anonymous_observers: true})

    assert {401, %{"error" => "log in to keep settings"}} = put("/api/settings/#{key}", 1)
    assert {401, %{"error" => "log in to keep settings"}} = request(:get, "/api/settings")

    assert {401, %{"error" => "invalid token"}} = request(:get, "/api/settings?token=forged")

    assert {200, _} = put("/api/settings/#{key}", "ada's", bearer("ada"))
    assert {200, _} = put("/api/settings/#{key}", "olga's", bearer("olga"))

    assert {200, %{"value" => "ada's"}} = request(:get, "/api/settings/#{key}", bearer("ada"))

    token = Token.sign("olga", @secret, System.os_time(:second), 600)
    assert {200, %{"value" => "olga's"}} = request(:get, "/api/settings/#{key}?token=#{token}")

    assert {200, %{"user" => "ada"}} = request(:get, "/api/settings", bearer("ada"))
    assert Settings.get({:user, "local"}, key) == :error
  end

  test "secure mode without anonymous observers: a token is needed", %{key: key} do
    secure!(@secret, %{"ada" => %{name: "ada", role: :pilot, hash: "unused"}})
    assert {401, _} = request(:get, "/api/settings/#{key}")
    assert {404, _} = request(:get, "/api/settings/#{key}", bearer("ada"))
  end
end
