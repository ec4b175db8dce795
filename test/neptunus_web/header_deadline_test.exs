defmodule NeptunusWeb.HeaderDeadlineTest do
  use ExUnit.Case, async: true

  alias NeptunusWeb.HeaderDeadline

  import ExUnit.CaptureLog

  doctest HeaderDeadline

  @timeout 5_000

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
    port = Application.fetch_env!(:neptunus, :endpoint).port
    {:ok, trickler} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false])
    :ok = :gen_tcp.send(trickler, "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n")

    {:ok, served} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false])
    :ok = :gen_tcp.send(served, "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    assert {:ok, "HTTP/1.1 200" <> _} = :gen_tcp.recv(served, 0, 5_000)

    # a header line well within yaws' per-read timeout, again and again, until closed
    timeout = NeptunusWeb.Endpoint.header_timeout_ms()

    log =
      capture_log(fn ->
        lines = trickle(trickler, 0, div(timeout, 10))
        assert lines < 30, "the trickler sent #{lines} lines and was never closed"
        NeptunusWeb.ConnectionLog.flush()
      end)

    # counted as slow, not idle: it sent bytes
    assert log =~ ~r/\[warning\] closed \d+ connections: .*\d+ slower than the header timeout/
    :gen_tcp.close(served)
  end

  test "a kept-alive connection asking again and again is never closed, however long it lives" do
    # yaws clears a connection's process dictionary after each request: between requests
    # every wait looks alike but for the answers sent (a browser reusing a connection was
    # cut off the timeout after it was first seen waiting, busy or not)
    port = Application.fetch_env!(:neptunus, :endpoint).port
    timeout = NeptunusWeb.Endpoint.header_timeout_ms()
    {:ok, socket} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false])
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
    port = Application.fetch_env!(:neptunus, :endpoint).port
    timeout = NeptunusWeb.Endpoint.header_timeout_ms()
    {:ok, socket} = :gen_tcp.connect(~c"127.0.0.1", port, [:binary, active: false])
    started = System.monotonic_time(:millisecond)
    lines = empty_lines(socket, 0, div(timeout, 5))
    lasted = System.monotonic_time(:millisecond) - started

    assert lines < 40, "#{lines} empty lines sent and the connection was never closed"
    assert lasted < 2 * timeout, "closed after #{lasted} ms"
  end

  defp empty_lines(_socket, 40, _every), do: 40

  defp empty_lines(socket, n, every) do
    Process.sleep(every)

    with :ok <- :gen_tcp.send(socket, "\r\n"),
         {:error, :timeout} <- :gen_tcp.recv(socket, 0, 0) do
      empty_lines(socket, n + 1, every)
    else
      _ -> n
    end
  end

  # one whole answer (head and a body of Content-Length bytes)
  defp recv_answer(socket, acc) do
    with [head, body] <- String.split(acc, "\r\n\r\n", parts: 2),
         [_, length] <- Regex.run(~r/content-length: *(\d+)/i, head),
         true <- byte_size(body) >= String.to_integer(length) do
      {:ok, acc}
    else
      _ ->
        case :gen_tcp.recv(socket, 0, 5_000) do
          {:ok, more} -> recv_answer(socket, acc <> more)
          error -> error
        end
    end
  end

  defp trickle(_socket, 40, _every), do: 40

  defp trickle(socket, n, every) do
    Process.sleep(every * 2)

    with :ok <- :gen_tcp.send(socket, "X-#{n}: 1\r\n"),
         {:error, :timeout} <- :gen_tcp.recv(socket, 0, 0) do
      trickle(socket, n + 1, every)
    else
      _ -> n
    end
  end
end
