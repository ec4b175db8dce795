defmodule NeptunusWeb.EndpointSupervisionTest do
  # The endpoint's helpers (rate limiter, connection log, header deadline) crash and restart
  # without taking yaws, or any connection, with them. Kills application-wide processes, so
  # it runs alone (async: false).
  use ExUnit.Case, async: false

  alias Neptunus.Test.Starvation
  alias NeptunusWeb.Test.{Wire, WSClient}

  @moduletag :capture_log

  setup do
    Wire.start_vehicle!("endpoint-sup")
  end

  for helper <- [
        NeptunusWeb.Auth.RateLimit,
        NeptunusWeb.Endpoint.ConnectionLog,
        NeptunusWeb.Endpoint.HeaderDeadline
      ] do
    test "killing #{inspect(helper)} keeps the pilot's connection and control", %{topic: topic} do
      helper = unquote(helper)
      pilot = Wire.client!(topic, %{name: "pilot"})
      assert {"ok", _} = Wire.push_and_reply(pilot.ws, pilot.jr, topic, "request_control", %{})
      Wire.event!(pilot.ws, "control_granted")
      yaws = Process.whereis(NeptunusWeb.Endpoint.Server)

      pid = Process.whereis(helper)
      ref = Process.monitor(pid)
      Process.exit(pid, :kill)
      assert_receive {:DOWN, ^ref, :process, ^pid, :killed}

      # it comes back, alone
      Neptunus.Test.Pty.wait_until(
        fn -> is_pid(Process.whereis(helper)) and Process.whereis(helper) != pid end,
        "#{inspect(helper)} to restart"
      )

      assert Process.whereis(NeptunusWeb.Endpoint.Server) == yaws
      # the pilot's connection is still open and still in control
      refute_receive {:ws, _, {:close, _, _}}, 300
      refute_received {:ws, _, :closed}
      assert {"ok", _} = Wire.push_and_reply(pilot.ws, pilot.jr, topic, "heartbeat", %{})
      assert %{pilot: %{}} = Neptunus.Vehicle.Helm.status(String.trim_leading(topic, "vehicle:"))
      WSClient.close(pilot.ws)
    end
  end

  # The issue's bound (R2): the service is back within 1 s of a crash — plus the time a busy
  # machine kept the node from a core meanwhile (Neptunus.Test.Starvation, as in the chaos
  # test: a wall-clock promise alone fails on a loaded machine with no fault in the code).
  test "a crash of one of yaws' processes: a client is granted control again within 1 s",
       %{topic: topic} do
    starvation = Starvation.start_link()
    pilot = Wire.client!(topic, %{name: "pilot"})
    assert {"ok", _} = Wire.push_and_reply(pilot.ws, pilot.jr, topic, "request_control", %{})
    Wire.event!(pilot.ws, "control_granted")

    # a kept-alive HTTP connection, as a browser holds one
    {200, _, _, _socket} = Wire.raw_get("/")

    pid = Process.whereis(:yaws_ws_sup)
    t0 = System.monotonic_time(:millisecond)
    Process.exit(pid, :kill)
    assert_receive {:ws, _, :closed}

    granted_at =
      Enum.find_value(1..100, fn _ ->
        with {:ok, ws} <- Wire.connect(%{name: "pilot"}),
             {:ok, _} <- safe_join(ws, topic),
             {"ok", %{"status" => "granted"}} <-
               Wire.push_and_reply(ws, "1", topic, "request_control", %{}) do
          System.monotonic_time(:millisecond)
        else
          _ ->
            Process.sleep(20)
            nil
        end
      end)

    starved = Starvation.waited(starvation, t0, granted_at)

    assert granted_at - t0 <= 1_000 + (starved || 0),
           "granted #{granted_at - t0} ms after the crash, the node kept from a core #{starved} ms"
  end

  # yaws' listening process is linked to its server process: killed at once, the server
  # made it log "Top proc died, terminate gserv" as an error at every clean stop.
  test "a clean stop of the web server logs no error, closes the connections, and it starts again",
       %{topic: topic} do
    _pilot = Wire.client!(topic, %{name: "pilot"})
    Process.flag(:trap_exit, true)

    # whatever fails below, the next tests find the web server up
    on_exit(fn ->
      Supervisor.restart_child(NeptunusWeb.Endpoint, NeptunusWeb.Endpoint.Server)
    end)

    starvation = Starvation.start_link()

    log =
      ExUnit.CaptureLog.capture_log([level: :error], fn ->
        t0 = System.monotonic_time(:millisecond)
        :ok = Supervisor.terminate_child(NeptunusWeb.Endpoint, NeptunusWeb.Endpoint.Server)
        stop_ms = System.monotonic_time(:millisecond) - t0
        # within 1 s, plus the time a busy machine kept the node from a core meanwhile
        starved = Starvation.waited(starvation, t0, t0 + stop_ms)

        assert stop_ms < 1_000 + (starved || 0),
               "the web server took #{stop_ms} ms to stop, the node kept from a core #{starved} ms"

        assert_receive {:ws, _, :closed}
        # what yaws' processes log as they end has reached the logger
        Process.sleep(200)
      end)

    refute log =~ "Top proc died"
    refute log =~ "[error]", "a clean stop logged an error:\n#{log}"

    {:ok, _} = Supervisor.restart_child(NeptunusWeb.Endpoint, NeptunusWeb.Endpoint.Server)

    Neptunus.Test.Pty.wait_until(
      fn -> match?({200, _, _, _}, Wire.raw_get("/")) end,
      "the web server to serve again"
    )

    again = Wire.client!(topic, %{name: "pilot"})

    assert {"ok", %{"status" => "granted"}} =
             Wire.push_and_reply(again.ws, again.jr, topic, "request_control", %{})

    WSClient.close(again.ws)
  end

  defp safe_join(ws, topic) do
    WSClient.join(ws, topic, %{}, "1")
  catch
    _, _ -> :error
  end
end
