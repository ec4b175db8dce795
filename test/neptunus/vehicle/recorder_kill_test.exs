defmodule Neptunus.Vehicle.RecorderKillTest do
  # A node that records is killed outright (SIGKILL to its OS process, as the kernel's OOM
  # killer or `kill -9` would): the recording on disk holds everything the vehicle broadcast
  # up to 0.25 s before the node's last broadcast, and reads back.
  use ExUnit.Case, async: true

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  alias Neptunus.Recording

  @moduletag :boot
  @moduletag :tmp_dir
  @moduletag timeout: 120_000
  @root Path.expand("../../..", __DIR__)
  @bound_ms 250

  # The node under test records its simulated vehicle. A witness process subscribed like the
  # recorder writes every broadcast it gets, with the wall clock, straight to a raw file (one
  # write(2) each, so the kernel has it when the node dies); a "mark" event goes out every
  # 700 ms, so telemetry mostly depends on the recorder's periodic sync.
  @script ~S"""
  topic = "vehicle:neptunus-1"

  spawn(fn ->
    {:ok, fd} = :file.open(System.fetch_env!("WITNESS"), [:raw, :write, :binary])
    :ok = Neptunus.PubSub.subscribe(topic)

    Stream.repeatedly(fn ->
      receive do
        {:pubsub, _, "telemetry", %{t: t}} ->
          :ok = :file.write(fd, "telemetry #{t} #{System.os_time(:millisecond)}\n")

        {:pubsub, _, "mark", %{n: n}} ->
          :ok = :file.write(fd, "mark #{n} #{System.os_time(:millisecond)}\n")

        _ ->
          :ok
      end
    end)
    |> Stream.run()
  end)

  spawn(fn ->
    Stream.iterate(1, &(&1 + 1))
    |> Enum.each(fn n ->
      Process.sleep(700)
      Neptunus.PubSub.broadcast(topic, "mark", %{n: n})
    end)
  end)

  IO.puts("PID #{System.pid()}")
  Process.sleep(:infinity)
  """

  test "kill -9 loses at most 0.25 s of telemetry and no event before that", %{tmp_dir: dir} do
    recordings = Path.join(dir, "recordings")
    witness = Path.join(dir, "witness")
    mix = System.find_executable("mix") || flunk("mix not found")

    port =
      Port.open({:spawn_executable, mix}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        {:line, 4096},
        {:cd, @root},
        {:args, ["run", "--no-compile", "-e", @script]},
        {:env,
         [
           {~c"MIX_ENV", ~c"test"},
           {~c"NEPTUNUS_PORT", ~c"#{free_port()}"},
           {~c"NEPTUNUS_VEHICLES", ~c"neptunus-1=simulated"},
           {~c"NEPTUNUS_RECORDINGS", String.to_charlist(recordings)},
           {~c"NEPTUNUS_RECORDING_MIN_FREE_MB", ~c"1"},
           {~c"WITNESS", String.to_charlist(witness)}
         ]}
      ])

    os_pid = await_pid(port, [])
    # whatever happens to the test, the node goes
    on_exit(fn -> System.cmd("kill", ["-9", os_pid], stderr_to_stdout: true) end)

    # let it record a few seconds: at least 3 marks and 60 telemetry broadcasts witnessed
    wait_for(fn ->
      lines = read_witness(witness)
      Enum.count(lines, &match?({"mark", _, _}, &1)) >= 3 and length(lines) >= 63
    end)

    {_, 0} = System.cmd("kill", ["-9", os_pid])
    assert_receive {^port, {:exit_status, status}}
    assert status != 0

    witnessed = read_witness(witness)
    [file] = Path.wildcard(Path.join([recordings, "neptunus-1", "*.log"]))
    # readable as it was left (repair on open), like Neptunus.Recording reads any recording
    recorded = file |> Recording.entries() |> Enum.to_list()

    newest = witnessed |> Enum.map(fn {_, _, at} -> at end) |> Enum.max()

    for kind <- ["telemetry", "mark"] do
      seen = for {^kind, value, at} <- witnessed, do: {value, at}
      on_disk = for {_, event, payload} <- recorded, event == kind, do: key(kind, payload)

      # what is on disk is what was broadcast, in order, with no hole ...
      seen_values = Enum.map(seen, &elem(&1, 0))
      from_first_seen = Enum.drop_while(on_disk, &(&1 != hd(seen_values)))
      assert from_first_seen == Enum.take(seen_values, length(from_first_seen))

      # ... up to at least 0.25 s before the node's last broadcast
      due = for {value, at} <- seen, at <= newest - @bound_ms, do: value

      missing = due -- from_first_seen

      assert missing == [],
             "#{kind} broadcast more than #{@bound_ms} ms before the kill is missing: " <>
               "#{inspect(missing)} (#{length(from_first_seen)} of #{length(seen)} on disk)"
    end
  end

  # as the witness wrote them
  defp key("telemetry", %{t: t}), do: to_string(t)
  defp key("mark", %{n: n}), do: Integer.to_string(n)

  defp await_pid(port, acc) do
    receive do
      {^port, {:data, {:eol, "PID " <> pid}}} ->
        pid

      {^port, {:data, {_, line}}} ->
        await_pid(port, [line | acc])

      {^port, {:exit_status, status}} ->
        flunk("the node exited (#{status}):\n" <> Enum.join(Enum.reverse(acc), "\n"))
    after
      60_000 -> flunk("the node did not start:\n" <> Enum.join(Enum.reverse(acc), "\n"))
    end
  end

  defp wait_for(fun, tries \\ 300) do
    cond do
      fun.() ->
        :ok

      tries == 0 ->
        flunk("the node did not record")

      true ->
        Process.sleep(100)
        wait_for(fun, tries - 1)
    end
  end

  # the witness' complete lines: {kind, value, wall clock ms}
  defp read_witness(path) do
    case File.read(path) do
      {:ok, text} ->
        text
        |> String.split("\n")
        |> Enum.drop(-1)
        |> Enum.map(fn line ->
          [kind, value, at] = String.split(line, " ")
          {kind, value, String.to_integer(at)}
        end)

      {:error, :enoent} ->
        []
    end
  end
end
