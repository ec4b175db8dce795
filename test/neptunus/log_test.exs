defmodule Neptunus.LogTest do
  # Client-supplied text in the server log: never a forged line.
  use ExUnit.Case, async: false

  import ExUnit.CaptureLog

  @moduletag :capture_log

  alias Neptunus.{Log, PubSub}
  alias Neptunus.Test.Properties
  alias Neptunus.Vehicle.{Helm, Telemetry}

  doctest Neptunus.Log

  @forged "x\n12:00:00.000 [error] vehicle neptunus-1: board link down\r\n\e[31mred"

  test "safe/1 leaves printable text alone and never lets a control character through" do
    assert Log.safe("ada's vehicle — 水中 ✓") == "ada's vehicle — 水中 ✓"
    assert Log.safe(:deadman) == "deadman"
    assert Log.safe({:a, "b"}) == ~s({:a, "b"})

    Properties.check(:proper_types.binary(), fn bin ->
      out = Log.safe(bin)

      String.valid?(out) and
        not Regex.match?(~r/[\x00-\x1F\x7F\x{80}-\x{9F}\x{2028}\x{2029}]/u, out)
    end)
  end

  test "safe/1 is one-to-one: different texts never log the same" do
    Properties.check(
      {:proper_types.binary(), :proper_types.binary()},
      fn {a, b} -> a == b or Log.safe(a) != Log.safe(b) end
    )
  end

  describe "a vehicle's log lines" do
    setup do
      id = "log-#{System.unique_integer([:positive])}"
      PubSub.subscribe(Telemetry.topic(id))
      start_supervised!({Neptunus.Vehicle.Supervisor, %{id: id, board: :simulated}})
      assert_receive {:pubsub, _, "stopped", %{reason: "helm_started"}}
      {:ok, id: id}
    end

    defp party(name) do
      pid = spawn(fn -> receive do: (:die -> :ok) end)

      %{
        id: "p-#{System.unique_integer([:positive])}",
        name: name,
        role: :pilot,
        pid: pid,
        notify: fn _, _ -> :ok end
      }
    end

    defp lines(log), do: log |> String.split("\n", trim: true)

    test "a pilot's stop reason with a newline stays on its line", %{id: id} do
      ada = party("ada")
      {:ok, %{status: "granted"}} = Helm.request_control(id, ada)

      log =
        capture_log(fn ->
          assert {:ok, _} = Helm.stop(id, ada, @forged)
          # what the client sent still reaches the clients as it was
          assert_receive {:pubsub, _, "stopped", %{reason: @forged}}
          Logger.flush()
        end)

      assert [line] = log |> lines() |> Enum.filter(&(&1 =~ "stopped:"))

      assert line =~
               ~S(stopped: x\n12:00:00.000 [error] vehicle neptunus-1: board link down\r\n\e[31mred)

      refute Enum.any?(lines(log), &String.starts_with?(&1, "12:00:00.000"))
    end

    test "a display name with a newline stays on its line", %{id: id} do
      # the notify of this party raises: the helm logs that, with the party's name
      pid = spawn(fn -> receive do: (:die -> :ok) end)

      party = %{
        id: "p-#{System.unique_integer([:positive])}",
        name: "eve\n12:00:00.000 [info] forged",
        role: :pilot,
        pid: pid,
        notify: fn _, _ -> raise "gone\nforged too" end
      }

      log =
        capture_log(fn ->
          {:ok, _} = Helm.request_control(id, party)
          Logger.flush()
        end)

      assert log =~ ~S(helm could not notify eve\n12:00:00.000 [info] forged: gone\nforged too)

      refute Enum.any?(
               lines(log),
               &(String.starts_with?(&1, "12:00:00.000") or &1 == "forged too")
             )
    end
  end
end
