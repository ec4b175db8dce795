defmodule Neptunus.Test.FakeArduSub do
  @moduledoc """
  Runs the fake ArduSub vehicle (`test/support/fake_ardusub.py`, pymavlink in the project's
  virtualenv) as a port: start it, read what it reports (JSON lines on its stdout: what it
  received and did), tell it what to do (JSON lines on its stdin). Owned by the calling test
  process, which gets its lines; the program exits when the port closes.
  """

  import ExUnit.Assertions

  alias Neptunus.Test.PyMAVLink

  @script Path.expand("fake_ardusub.py", __DIR__)

  @type t :: %{port: port(), udp: :inet.port_number() | nil, tcp: :inet.port_number() | nil}

  @doc """
  Starts the fake: `kind` `:udp` (an ephemeral UDP port) or `:tcp` (an ephemeral TCP port).
  Options: `frame:` its `FRAME_CONFIG` (default 1, vectored; 4 is a SimpleROV-3). Returns
  `%{port, udp | tcp}` once it listens.
  """
  @spec start!(:udp | :tcp, keyword()) :: t()
  def start!(kind \\ :udp, opts \\ []) do
    args = if kind == :tcp, do: [@script, "--tcp", "0"], else: [@script]
    args = args ++ ["--frame", Integer.to_string(Keyword.get(opts, :frame, 1))]

    port =
      Port.open({:spawn_executable, PyMAVLink.python!()}, [
        :binary,
        :exit_status,
        {:line, 4096},
        args: args,
        env: [{~c"MAVLINK20", ~c"1"}, {~c"PYTHONUNBUFFERED", ~c"1"}]
      ])

    ExUnit.Callbacks.on_exit(fn -> stop(port) end)
    %{"port" => listening} = expect!(%{port: port}, &(&1["event"] == "listening"), 10_000)
    Map.merge(%{port: port, udp: nil, tcp: nil}, %{kind => listening})
  end

  @doc "Stops the fake (closing the port closes its stdin: it exits)."
  @spec stop(port() | t()) :: :ok
  def stop(%{port: port}), do: stop(port)

  def stop(port) when is_port(port) do
    if Port.info(port), do: Port.close(port)
    :ok
  catch
    :error, _ -> :ok
  end

  @doc """
  Tells the fake `order` (a JSON object: `%{refuse_arm: text | nil}`, `%{frame: n}`,
  `%{answer_params: boolean}`, …; see fake_ardusub.py).
  """
  @spec tell(t(), map()) :: :ok
  def tell(%{port: port}, order) do
    true = Port.command(port, [:jiffy.encode(order), "\n"])
    :ok
  end

  @doc """
  The next report for which `pred` is true (reports before it are dropped), or a test
  failure after `timeout` ms (`Neptunus.Test.Patience`).
  """
  @spec expect!(%{port: port()}, (map() -> boolean()), timeout()) :: map()
  def expect!(fake, pred, timeout \\ Neptunus.Test.Patience.ms()) do
    case expect(fake, pred, timeout) do
      {:ok, report} -> report
      :timeout -> flunk("the fake ArduSub did not report what was expected in time")
    end
  end

  @doc "As `expect!/3`, but `:timeout` when nothing fitting came in `timeout` ms."
  @spec expect(%{port: port()}, (map() -> boolean()), timeout()) :: {:ok, map()} | :timeout
  def expect(%{port: port} = fake, pred, timeout) do
    deadline = System.monotonic_time(:millisecond) + timeout
    wait(fake, port, pred, deadline)
  end

  defp wait(fake, port, pred, deadline) do
    left = max(0, deadline - System.monotonic_time(:millisecond))

    receive do
      {^port, {:data, {:eol, line}}} ->
        report = :jiffy.decode(line, [:return_maps])
        if pred.(report), do: {:ok, report}, else: wait(fake, port, pred, deadline)

      {^port, {:exit_status, n}} ->
        flunk("the fake ArduSub exited (#{n})")
    after
      left -> :timeout
    end
  end

  @doc "Drops the reports received so far."
  @spec flush(t()) :: :ok
  def flush(%{port: port}) do
    receive do
      {^port, {:data, _}} -> flush(%{port: port})
    after
      0 -> :ok
    end
  end
end
