defmodule NeptunusWeb.Endpoint.ConnectionLogTest do
  use ExUnit.Case, async: true

  import ExUnit.CaptureLog

  alias NeptunusWeb.Endpoint.ConnectionLog

  doctest ConnectionLog

  defp event(msg), do: %{level: :error, msg: msg, meta: %{}}

  test "yaws' line for a connection closed beyond the limit is dropped and counted" do
    counters = :counters.new(2, [])
    format = ~c"Max connections reached - closing conn to ~s~n"

    # as error_logger:format/2 sends it, and as a plain format
    assert ConnectionLog.filter(
             event({:report, %{label: {:error_logger, :error_msg}, format: format, args: ["x"]}}),
             counters
           ) == :stop

    assert ConnectionLog.filter(event({format, ["x"]}), counters) == :stop
    assert :counters.get(counters, 1) == 2
  end

  test "every other event is left to the other filters, uncounted" do
    counters = :counters.new(2, [])

    for msg <- [
          {:string, "Max connections reached - closing conn to 1.2.3.4"},
          {:report, %{format: ~c"Yaws process died: ~p~n", args: [:x]}},
          {~c"Failed to accept: ~p~n", [:emfile]},
          {:report, %{anything: :else}}
        ] do
      assert ConnectionLog.filter(event(msg), counters) == :ignore
    end

    assert :counters.get(counters, 1) == 0
  end

  test "refuses to start on a yaws it was not written for, and leaves the running filter" do
    log =
      capture_log(fn ->
        assert {:error, {:unsupported_yaws, message}} =
                 GenServer.start(ConnectionLog, yaws_version: "2.0.6")

        assert message =~ "NeptunusWeb.Endpoint.ConnectionLog reads yaws' internals"
        assert message =~ "written for yaws 2.1.1; this node runs yaws 2.0.6"
      end)

    assert log =~ "ConnectionLog reads yaws' internals"
    # the endpoint's own log still counts yaws' lines
    assert :neptunus_connection_log in Keyword.keys(:logger.get_primary_config().filters)
  end
end
