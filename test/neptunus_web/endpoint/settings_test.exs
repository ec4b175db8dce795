defmodule NeptunusWeb.Endpoint.SettingsTest do
  # The web layer's settings: built from the configuration once, at boot
  # (Neptunus.Config.Endpoint.web_settings!/1), and read by the connections from
  # NeptunusWeb.Endpoint.Settings, never from the application environment.
  use ExUnit.Case, async: true

  alias Neptunus.Config.Endpoint
  alias NeptunusWeb.Endpoint.Settings

  doctest NeptunusWeb.Endpoint.Settings

  @endpoint %{port: 4000, bind: {127, 0, 0, 1}}

  test "every tuning key has its default; a configured value wins" do
    settings = Endpoint.web_settings!(endpoint: @endpoint)

    assert %Settings{
             port: 4000,
             bind: {127, 0, 0, 1},
             tls: nil,
             max_connections: nil,
             send_timeout_ms: 15_000,
             header_timeout_ms: 5_000,
             idle_timeout_ms: 60_000,
             pilot_frames_per_s: 200,
             backlog: 8,
             unsent_bytes: 4_096,
             recording_dir: nil
           } = settings

    assert settings.auth == Neptunus.Config.Auth.local()

    configured =
      Endpoint.web_settings!(
        endpoint:
          Map.merge(@endpoint, %{max_connections: 10, tls: %{certfile: "c", keyfile: "k"}}),
        send_timeout_ms: 2_000,
        header_timeout_ms: 1_000,
        socket_idle_timeout_ms: 300,
        pilot_frames_per_s: 20,
        socket_backlog: 3,
        socket_unsent_bytes: nil,
        recording: %{dir: "recs", max_bytes: 1},
        auth: %{mode: :secure, secret: "s", origins: ["https://rov.example"]}
      )

    assert %Settings{
             max_connections: 10,
             send_timeout_ms: 2_000,
             header_timeout_ms: 1_000,
             idle_timeout_ms: 300,
             pilot_frames_per_s: 20,
             backlog: 3,
             unsent_bytes: nil,
             recording_dir: "recs"
           } = configured

    # the configured security settings, completed by local mode's defaults
    assert %{mode: :secure, secret: "s", origins: ["https://rov.example"], token_ttl_s: 43_200} =
             configured.auth

    assert Settings.url(configured) == "https://127.0.0.1:4000"
    assert Settings.url(%{configured | bind: {0, 0, 0, 0, 0, 0, 0, 1}}) == "https://[::1]:4000"
  end

  test "a bad value is named in a clear error" do
    for {key, value} <- [
          send_timeout_ms: 0,
          header_timeout_ms: -1,
          socket_idle_timeout_ms: "60000",
          pilot_frames_per_s: 1.5,
          socket_backlog: nil,
          socket_unsent_bytes: 0
        ] do
      message = "config :neptunus, #{key}: #{inspect(value)} is not valid"

      assert_raise ArgumentError, ~r/^#{Regex.escape(message)}/, fn ->
        Endpoint.web_settings!([{:endpoint, @endpoint}, {key, value}])
      end
    end

    assert_raise ArgumentError, ~r/config :neptunus, endpoint: nil is not valid/, fn ->
      Endpoint.web_settings!([])
    end
  end

  test "the running endpoint serves with the settings it was started with" do
    settings = Settings.get()
    assert NeptunusWeb.Endpoint.url() == Settings.url(settings)
    assert NeptunusWeb.Endpoint.send_timeout_ms() == settings.send_timeout_ms
    assert NeptunusWeb.Endpoint.header_timeout_ms() == settings.header_timeout_ms
    assert NeptunusWeb.Auth.config() == settings.auth
  end

  test "no web module reads the application environment" do
    {:ok, modules} = :application.get_key(:neptunus, :modules)

    reads =
      for module <- modules,
          # the test support modules (NeptunusWeb.Test.*) are not the web layer
          String.starts_with?(Atom.to_string(module), "Elixir.NeptunusWeb."),
          not String.starts_with?(Atom.to_string(module), "Elixir.NeptunusWeb.Test."),
          {:ok, {^module, [imports: imports]}} =
            :beam_lib.chunks(:code.which(module), [:imports]),
          {Application, fun, arity} <- imports,
          fun in [:get_env, :fetch_env, :fetch_env!, :get_all_env],
          do: "#{inspect(module)} calls Application.#{fun}/#{arity}"

    assert reads == []
  end
end
