defmodule NeptunusWeb.Endpoint.HeaderDeadlineTest do
  use ExUnit.Case, async: true

  alias NeptunusWeb.Endpoint.HeaderDeadline

  import ExUnit.CaptureLog

  doctest HeaderDeadline

  @timeout 5_000

  test "refuses to start on a yaws it was not written for, and says what to check" do
    log =
      capture_log(fn ->
        assert {:error, {:unsupported_yaws, message}} =
                 GenServer.start(HeaderDeadline, timeout_ms: @timeout, yaws_version: "2.2.0")

        assert message =~ "NeptunusWeb.Endpoint.HeaderDeadline reads yaws' internals"
        assert message =~ "written for yaws 2.1.1; this node runs yaws 2.2.0"
        assert message =~ "add that version to its @yaws_versions"
      end)

    assert log =~ "HeaderDeadline reads yaws' internals"
  end

  test "starts on the yaws this node runs" do
    assert {:ok, pid} = GenServer.start(HeaderDeadline, timeout_ms: @timeout)
    GenServer.stop(pid)
  end

  test "a connection reading the same head is closed once the timeout has passed" do
    {seen, []} = HeaderDeadline.sweep(%{}, [{:a, {:request_line, nil}}], 1_000, @timeout)
    {seen, []} = HeaderDeadline.sweep(seen, [{:a, {:request_line, nil}}], 3_000, @timeout)
    {seen, []} = HeaderDeadline.sweep(seen, [{:a, {:request_line, nil}}], 5_999, @timeout)
    assert {%{}, [:a]} = HeaderDeadline.sweep(seen, [{:a, {:request_line, nil}}], 6_000, @timeout)
  end

  test "progress starts a fresh deadline: headers after the request line, a next request" do
    {seen, []} = HeaderDeadline.sweep(%{}, [{:a, {:request_line, nil}}], 0, @timeout)
    # the request line came: now reading its headers
    {seen, []} = HeaderDeadline.sweep(seen, [{:a, {:headers, :t1}}], 4_000, @timeout)
    {seen, []} = HeaderDeadline.sweep(seen, [{:a, {:headers, :t1}}], 8_000, @timeout)
    # the request was served; waiting on the kept-alive connection for the next one
    {seen, []} = HeaderDeadline.sweep(seen, [{:a, {:request_line, :t1}}], 8_500, @timeout)
    assert seen == %{a: {{:request_line, :t1}, 8_500}}
    # a next request (a new start time) between two sweeps
    {seen, []} = HeaderDeadline.sweep(seen, [{:a, {:headers, :t2}}], 13_000, @timeout)
    assert seen == %{a: {{:headers, :t2}, 13_000}}
  end

  test "a connection no longer reading a head (served, upgraded, closed) is forgotten" do
    {seen, []} =
      HeaderDeadline.sweep(%{}, [{:a, {:headers, 1}}, {:b, {:headers, 2}}], 0, @timeout)

    {seen, []} = HeaderDeadline.sweep(seen, [{:b, {:headers, 2}}], 3_000, @timeout)
    assert Map.keys(seen) == [:b]
    # back to reading later (a new request): a fresh deadline, not the old one
    {seen, expired} =
      HeaderDeadline.sweep(seen, [{:a, {:headers, 1}}, {:b, {:headers, 2}}], 5_000, @timeout)

    assert expired == [:b]
    assert seen == %{a: {{:headers, 1}, 5_000}}
  end

  test "several connections expire together, in the order observed" do
    reading = for n <- 1..5, do: {n, {:request_line, nil}}
    {seen, []} = HeaderDeadline.sweep(%{}, reading, 0, @timeout)
    assert {%{}, [1, 2, 3, 4, 5]} = HeaderDeadline.sweep(seen, reading, @timeout, @timeout)
  end

  test "the running process finds a trickling connection and closes it, not a served one" do
    trickler = connect!()
    :ok = :gen_tcp.send(trickler, "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n")

    served = connect!()
    :ok = :gen_tcp.send(served, "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    assert {:ok, "HTTP/1.1 200" <> _} = :gen_tcp.recv(served, 0, Neptunus.Test.Patience.ms())

    # a header line well within yaws' per-read timeout, again and again, until closed
    timeout = NeptunusWeb.Endpoint.header_timeout_ms()

    log =
      capture_log(fn ->
        lines = drip(trickler, div(timeout, 5), &"X-#{&1}: 1\r\n")
        assert lines < 30, "the trickler sent #{lines} lines and was never closed"
        NeptunusWeb.Endpoint.ConnectionLog.flush()
      end)

    # counted for the log, in one line
    assert log =~ ~r/\[warning\] closed \d+ connections: .*\d+ slower than the header timeout/
    :gen_tcp.close(served)
  end

  test "a kept-alive connection asking again and again is never closed, however long it lives" do
    # yaws clears a connection's process dictionary after each request: between requests
    # every wait looks alike but for the answers sent (a browser reusing a connection was
    # cut off the timeout after it was first seen waiting, busy or not)
    timeout = NeptunusWeb.Endpoint.header_timeout_ms()
    socket = connect!()
    every = div(timeout, 3)
    asks = div(2 * timeout, every) + 2

    for n <- 1..asks do
      :ok = :gen_tcp.send(socket, "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
      assert {:ok, "HTTP/1.1 200" <> _ = answer} = recv_answer(socket, ""), "request #{n}"
      assert answer =~ "\r\n\r\n"
      Process.sleep(every)
    end

    :gen_tcp.close(socket)
  end

  test "empty lines instead of a request line do not hold a connection" do
    # yaws skips an empty line with a fresh read timeout: only the deadline ends this
    timeout = NeptunusWeb.Endpoint.header_timeout_ms()
    starvation = Neptunus.Test.Starvation.start_link()
    socket = connect!()
    started = System.monotonic_time(:millisecond)
    lines = drip(socket, div(timeout, 5), fn _ -> "\r\n" end)
    lasted = System.monotonic_time(:millisecond) - started

    assert lines < 40, "#{lines} empty lines sent and the connection was never closed"
    # within two timeouts, plus the time a busy machine kept the node from a core meanwhile
    starved = Neptunus.Test.Starvation.waited(starvation, started, started + lasted)

    assert lasted < 2 * timeout + (starved || 0),
           "closed after #{lasted} ms, the node kept from a core #{starved} ms"
  end

  @tag :tmp_dir
  test "the bytes sent on a connection are read over TCP and over TLS", %{tmp_dir: dir} do
    # over TLS the TCP socket belongs to ssl's connection process, not to yaws' acceptor
    tls = Neptunus.Test.Cluster.Netns.certificates!(dir, ["127.0.0.1"])
    {:ok, _} = Application.ensure_all_started(:ssl)

    tcp = {:gen_tcp, [], []}
    ssl = {:ssl, Map.to_list(Map.take(tls, [:certfile, :keyfile])), [verify: :verify_none]}

    for {transport, listen_opts, connect_opts} <- [tcp, ssl] do
      {:ok, listener} = transport.listen(0, [:binary, active: false] ++ listen_opts)
      {:ok, {_, port}} = sockname(transport, listener)
      test = self()

      acceptor =
        spawn_link(fn ->
          {:ok, socket} = accept(transport, listener)
          send(test, :accepted)
          {:ok, "ask"} = transport.recv(socket, 3, Neptunus.Test.Patience.ms())
          :ok = transport.send(socket, "answer")
          send(test, :answered)
          transport.recv(socket, 0, Neptunus.Test.Patience.ms())
        end)

      {:ok, client} =
        transport.connect(~c"127.0.0.1", port, [:binary, active: false] ++ connect_opts)

      assert_receive :accepted
      before = HeaderDeadline.sent_bytes(acceptor)
      assert is_integer(before), "#{transport}: no socket found"

      :ok = transport.send(client, "ask")
      assert_receive :answered
      assert HeaderDeadline.sent_bytes(acceptor) > before, "#{transport}: the answer not counted"

      transport.close(client)
      transport.close(listener)
    end
  end

  defp sockname(:gen_tcp, listener), do: :inet.sockname(listener)
  defp sockname(:ssl, listener), do: :ssl.sockname(listener)

  defp accept(:gen_tcp, listener), do: :gen_tcp.accept(listener, Neptunus.Test.Patience.ms())

  defp accept(:ssl, listener) do
    {:ok, socket} = :ssl.transport_accept(listener, Neptunus.Test.Patience.ms())
    :ssl.handshake(socket, Neptunus.Test.Patience.ms())
  end

  defp connect! do
    port = Application.fetch_env!(:neptunus, :endpoint).port
    {:ok, socket} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false])
    socket
  end

  # one whole answer (head and a body of Content-Length bytes)
  defp recv_answer(socket, acc) do
    with [head, body] <- String.split(acc, "\r\n\r\n", parts: 2),
         [_, length] <- Regex.run(~r/content-length: *(\d+)/i, head),
         true <- byte_size(body) >= String.to_integer(length) do
      {:ok, acc}
    else
      _ ->
        case :gen_tcp.recv(socket, 0, Neptunus.Test.Patience.ms()) do
          {:ok, more} -> recv_answer(socket, acc <> more)
          error -> error
        end
    end
  end

  # Sends line(n) every `every` ms until the server closes the connection (or 40 lines):
  # the number of lines it took.
  defp drip(socket, every, line, n \\ 0)
  defp drip(_socket, _every, _line, 40), do: 40

  defp drip(socket, every, line, n) do
    Process.sleep(every)

    with :ok <- :gen_tcp.send(socket, line.(n)),
         {:error, :timeout} <- :gen_tcp.recv(socket, 0, 0) do
      drip(socket, every, line, n + 1)
    else
      _ -> n
    end
  end
end
