defmodule Neptunus.Test.GCSClient do
  @moduledoc """
  A ground station for the tests of `Neptunus.GCS`: MAVLink over UDP with the project's
  codec (signed when given a key), in a process that keeps what it receives and reports
  nothing on its own; `expect/3` waits for a message the test describes.

      gcs = GCSClient.start!(port)            # to a udpin endpoint on 127.0.0.1:port
      GCSClient.send!(gcs, :heartbeat, %{...})
      GCSClient.expect!(gcs, &(&1.name == :heartbeat and &1.system == 1))
  """
  use GenServer

  alias Neptunus.Protocol.MAVLink
  alias Neptunus.Protocol.MAVLink.Signing

  defstruct [
    :socket,
    :host,
    :port,
    :sysid,
    :key,
    :link_id,
    seq: 0,
    ts: 0,
    decoder: %MAVLink.Decoder{},
    received: [],
    waiting: nil,
    streams: %{}
  ]

  @doc """
  A client sending to `port` on loopback from system `sysid` (255), component 190.
  Options: `:sysid`, `:key` (sign with it), `:link_id`, `:listen` (a port to receive on
  instead of an ephemeral one: a udpout's peer).
  """
  def start!(port, opts \\ []) do
    {:ok, pid} = GenServer.start_link(__MODULE__, {port, opts})
    pid
  end

  @doc "Sends a message (signed when the client has a key)."
  def send!(pid, name, fields, opts \\ []), do: GenServer.call(pid, {:send, name, fields, opts})

  @doc """
  Sends a message every `every_ms` from now on, as a ground station streams MANUAL_CONTROL
  (10 Hz) or its HEARTBEAT (1 Hz); `stop_stream/2` stops it.
  """
  def stream!(pid, name, fields, every_ms),
    do: GenServer.call(pid, {:stream, name, fields, every_ms})

  @doc "Stops streaming message `name`."
  def stop_stream(pid, name), do: GenServer.call(pid, {:stop_stream, name})

  @doc "Sends COMMAND_LONG `command` to component 1 of system `target` with up to 7 params."
  def command!(pid, target, command, params),
    do: send!(pid, :command_long, command_long(target, command, params))

  @doc """
  The fields of a COMMAND_LONG to system `target`, component 1: `command` with `params`, the
  first seven of them (numbers as floats, atoms such as `:nan` as they are), the rest 0.0.
  """
  def command_long(target, command, params) do
    [p1, p2, p3, p4, p5, p6, p7] =
      (params ++ List.duplicate(0.0, 7))
      |> Enum.take(7)
      |> Enum.map(&if(is_atom(&1), do: &1, else: &1 * 1.0))

    %{
      target_system: target,
      target_component: 1,
      command: command,
      confirmation: 0,
      param1: p1,
      param2: p2,
      param3: p3,
      param4: p4,
      param5: p5,
      param6: p6,
      param7: p7
    }
  end

  @doc "Sends raw bytes."
  def send_raw!(pid, bytes), do: GenServer.call(pid, {:raw, bytes})

  @doc "The frame the client would send (for replays and tampering)."
  def frame!(pid, name, fields), do: GenServer.call(pid, {:frame, name, fields})

  @doc "Waits up to `ms` for a received message `fun` accepts (from the oldest on), or fails."
  def expect!(pid, fun, ms \\ 3_000) do
    case GenServer.call(pid, {:expect, fun, ms}, ms + 1_000) do
      {:ok, message} ->
        message

      :timeout ->
        raise ExUnit.AssertionError, message: "no matching MAVLink message within #{ms} ms"
    end
  end

  @doc "Whether a message `fun` accepts arrives within `ms` (consumed if it does)."
  def arrives?(pid, fun, ms),
    do: match?({:ok, _}, GenServer.call(pid, {:expect, fun, ms}, ms + 1_000))

  @doc "Forgets what was received so far."
  def flush(pid), do: GenServer.call(pid, :flush)

  @doc "Every message received so far (and keeps them)."
  def received(pid), do: GenServer.call(pid, :received)

  def stop(pid), do: GenServer.stop(pid)

  @impl true
  def init({port, opts}) do
    {:ok, socket} =
      :gen_udp.open(Keyword.get(opts, :listen, 0), [:binary, active: true, ip: {127, 0, 0, 1}])

    {:ok,
     %__MODULE__{
       socket: socket,
       host: {127, 0, 0, 1},
       port: port,
       sysid: Keyword.get(opts, :sysid, 255),
       key: Keyword.get(opts, :key),
       link_id: Keyword.get(opts, :link_id, 0),
       ts: Signing.timestamp(System.os_time(:microsecond))
     }}
  end

  @impl true
  def handle_call({:send, name, fields, opts}, _from, state) do
    {frame, state} = frame(state, name, fields, opts)
    :ok = :gen_udp.send(state.socket, state.host, state.port, frame)
    {:reply, :ok, state}
  end

  def handle_call({:frame, name, fields}, _from, state) do
    {frame, state} = frame(state, name, fields, [])
    {:reply, frame, state}
  end

  def handle_call({:raw, bytes}, _from, state) do
    :ok = :gen_udp.send(state.socket, state.host, state.port, bytes)
    {:reply, :ok, state}
  end

  def handle_call({:expect, fun, ms}, from, state) do
    case take(state.received, fun) do
      {:ok, message, rest} ->
        {:reply, {:ok, message}, %{state | received: rest}}

      :none ->
        timer = Process.send_after(self(), {:expect_timeout, from}, ms)
        {:noreply, %{state | waiting: {from, fun, timer}}}
    end
  end

  def handle_call({:stream, name, fields, every_ms}, _from, state) do
    send(self(), {:stream, name, fields, every_ms})
    {:reply, :ok, %{state | streams: Map.put(state.streams, name, fields)}}
  end

  def handle_call({:stop_stream, name}, _from, state),
    do: {:reply, :ok, %{state | streams: Map.delete(state.streams, name)}}

  def handle_call(:flush, _from, state), do: {:reply, :ok, %{state | received: []}}
  def handle_call(:received, _from, state), do: {:reply, state.received, state}

  @impl true
  def handle_info({:udp, _socket, _ip, _port, data}, state) do
    {decoder, messages, _events} = MAVLink.decode(state.decoder, data)
    state = %{state | decoder: decoder, received: state.received ++ messages}

    case state.waiting do
      {from, fun, timer} ->
        case take(state.received, fun) do
          {:ok, message, rest} ->
            Process.cancel_timer(timer)
            GenServer.reply(from, {:ok, message})
            {:noreply, %{state | received: rest, waiting: nil}}

          :none ->
            {:noreply, state}
        end

      nil ->
        {:noreply, state}
    end
  end

  def handle_info({:expect_timeout, from}, %{waiting: {from, _, _}} = state) do
    GenServer.reply(from, :timeout)
    {:noreply, %{state | waiting: nil}}
  end

  def handle_info({:stream, name, fields, every_ms}, state) do
    case state.streams do
      %{^name => ^fields} ->
        {frame, state} = frame(state, name, fields, [])
        :ok = :gen_udp.send(state.socket, state.host, state.port, frame)
        Process.send_after(self(), {:stream, name, fields, every_ms}, every_ms)
        {:noreply, state}

      _ ->
        {:noreply, state}
    end
  end

  def handle_info(_msg, state), do: {:noreply, state}

  defp take(messages, fun) do
    case Enum.split_while(messages, &(not fun.(&1))) do
      {_before, []} -> :none
      {before, [message | rest]} -> {:ok, message, before ++ rest}
    end
  end

  defp frame(state, name, fields, opts) do
    sysid = Keyword.get(opts, :sysid, state.sysid)
    seq = state.seq
    {:ok, frame} = MAVLink.encode(name, fields, %{system: sysid, component: 190, seq: seq})
    state = %{state | seq: rem(seq + 1, 256)}
    key = Keyword.get(opts, :key, state.key)

    case key do
      nil ->
        {frame, state}

      key ->
        ts = Signing.next_timestamp(Signing.timestamp(System.os_time(:microsecond)), state.ts)
        {Signing.sign(frame, seq, key, state.link_id, ts), %{state | ts: ts}}
    end
  end
end
