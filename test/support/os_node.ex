defmodule Neptunus.Test.OSNode do
  @moduledoc """
  A Neptunus node as an OS process of its own (`mix run --no-compile -e SCRIPT` in the test
  environment, a port of the test), for tests that kill it outright or change the world
  under it: it prints `PID <os pid>` once its script runs. A witness file, written by the
  script one `write(2)` per line (`kind value wall_ms`), tells the test what the node saw,
  even after the node is killed.
  """
  import ExUnit.Assertions, only: [flunk: 1]

  import Neptunus.Test.Vehicles, only: [free_port: 0]

  @root Path.expand("../..", __DIR__)

  @doc """
  Starts the node: `script` run by `mix run`, `env` added to the node's environment
  (`NEPTUNUS_VEHICLES=neptunus-1=simulated`, a free `NEPTUNUS_PORT` and a 1 MiB disk reserve
  by default); `wrap` is a program and its arguments that run `mix` (their last argument
  is the command line, for `sh -c`), or nil. The port and the node's HTTP port.
  """
  @spec start(String.t(), [{charlist(), charlist()}], {String.t(), [String.t()]} | nil) ::
          {port(), :inet.port_number()}
  def start(script, env, wrap \\ nil) do
    mix = System.find_executable("mix") || flunk("mix not found")
    http = free_port()

    {program, args} =
      case wrap do
        nil -> {mix, ["run", "--no-compile", "-e", script]}
        {program, args} -> {program, args ++ [mix, "run", "--no-compile", "-e", script]}
      end

    port =
      Port.open({:spawn_executable, program}, [
        :binary,
        :exit_status,
        :stderr_to_stdout,
        {:line, 4096},
        {:cd, @root},
        {:args, args},
        {:env,
         [
           {~c"MIX_ENV", ~c"test"},
           {~c"NEPTUNUS_PORT", ~c"#{http}"},
           {~c"NEPTUNUS_VEHICLES", ~c"neptunus-1=simulated"},
           {~c"NEPTUNUS_RECORDING_MIN_FREE_MB", ~c"1"}
         ] ++ env}
      ])

    {port, http}
  end

  @doc "The node's OS pid, once its script printed it (flunks when the node exits first)."
  @spec await_pid(port()) :: String.t()
  def await_pid(port), do: await_pid(port, [])

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

  @doc "Waits (polling every 100 ms, at most 30 s) until `fun` returns true; flunks then."
  @spec wait_for((() -> boolean()), String.t()) :: :ok
  def wait_for(fun, what, tries \\ 300) do
    cond do
      fun.() ->
        :ok

      tries == 0 ->
        flunk("the node did not #{what}")

      true ->
        Process.sleep(100)
        wait_for(fun, what, tries - 1)
    end
  end

  @doc "The witness file's complete lines: `{kind, value, wall clock ms}`."
  @spec read_witness(Path.t()) :: [{String.t(), String.t(), integer()}]
  def read_witness(path) do
    case File.read(path) do
      {:ok, text} ->
        text
        |> String.split("\n")
        |> Enum.drop(-1)
        |> Enum.map(fn line ->
          [kind, rest] = String.split(line, " ", parts: 2)
          [at, value] = rest |> String.reverse() |> String.split(" ", parts: 2)
          {kind, String.reverse(value), at |> String.reverse() |> String.to_integer()}
        end)

      {:error, :enoent} ->
        []
    end
  end
end
