defmodule NeptunusWeb.APITest do
  # The router's own answers, against the running endpoint: a path it does not know, and a
  # method a path does not take, with the methods it does. What each resource answers is
  # tested in test/neptunus_web/api/.
  use ExUnit.Case, async: true

  defp request(method, path) do
    url = ~c"http://127.0.0.1:#{Application.fetch_env!(:neptunus, :endpoint).port}#{path}"

    request =
      if method in [:post, :put], do: {url, [], ~c"application/json", "{}"}, else: {url, []}

    {:ok, {{_, status, _}, headers, body}} =
      :httpc.request(method, request, [], body_format: :binary)

    content_type = for {~c"content-type", value} <- headers, do: to_string(value)
    {status, content_type, :jiffy.decode(body, [:return_maps])}
  end

  test "a method a path does not take is refused with 405 and the methods it takes" do
    for {method, path, methods} <- [
          {:post, "/api/health", "GET"},
          {:get, "/api/login", "POST"},
          {:delete, "/api/session", "GET"},
          {:put, "/api/recordings", "GET (or DELETE for one recording)"},
          {:post, "/api/recordings/rov/20200101-000000Z-1.log",
           "GET (or DELETE for one recording)"},
          {:delete, "/api/settings", "GET (or GET, PUT, DELETE for one setting)"},
          {:post, "/api/settings/gamepad", "GET, PUT or DELETE"}
        ] do
      assert request(method, path) ==
               {405, ["application/json"], %{"error" => "method not allowed: use #{methods}"}},
             "#{method} #{path}"
    end
  end

  test "a path the API does not have is 404, whatever the method" do
    for method <- [:get, :post, :delete], path <- ["/api/nope", "/api/health/x", "/api"] do
      assert {404, ["application/json"], %{"error" => "no such API endpoint: " <> ^path}} =
               request(method, path)
    end
  end
end
