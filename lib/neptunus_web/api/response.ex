defmodule NeptunusWeb.API.Response do
  @moduledoc """
  The API's answers as yaws' `out/1` results. A resource answers `{status, body}` or
  `{status, body, headers}` (a JSON body, never cached), or yaws' own list (a streamed body,
  `stream/3`); `respond/1` turns the first two into yaws' list. `NeptunusWeb.CameraStream`
  answers its errors the same way.
  """
  import NeptunusWeb.Endpoint.Yaws, only: [await_stream: 3]

  require Logger

  alias Neptunus.JSON

  @typedoc "What a resource answers (see the moduledoc)."
  @type t ::
          {pos_integer(), map()}
          | {pos_integer(), map(), [{String.t(), String.t() | integer()}]}
          | [tuple()]

  @statuses %{invalid: 400, not_found: 404, conflict: 409, unreachable: 503, failed: 500}

  @doc """
  The answer to a request the core refused, `{:error, kind, reason}` (as
  `Neptunus.Recording.Pull` and `Neptunus.Camera.Snapshots` refuse): `:invalid` 400,
  `:not_found` 404, `:conflict` 409, `:unreachable` 503, `:failed` 500.
  """
  @spec refused({:error, :invalid | :not_found | :conflict | :unreachable | :failed, String.t()}) ::
          {pos_integer(), map()}
  def refused({:error, kind, reason}), do: {Map.fetch!(@statuses, kind), %{error: reason}}

  @doc "A resource's answer as yaws' `out/1` result: JSON with `Cache-Control: no-store`."
  @spec respond(t()) :: [tuple()]
  def respond([{:status, _} | _] = response), do: response
  def respond({status, body}), do: respond({status, body, []})

  def respond({status, body, headers}) do
    [
      {:status, status},
      {:header, {:cache_control, ~c"no-store"}}
      | Enum.map(headers, fn {name, value} ->
          {:header, {String.to_charlist(name), header_value(value)}}
        end)
    ] ++ [{:content, ~c"application/json", JSON.encode!(body)}]
  end

  defp header_value(value) when is_integer(value), do: Integer.to_charlist(value)
  defp header_value(value), do: String.to_charlist(value)

  @chunk_bytes 65_536

  @doc """
  The part of yaws' answer that streams the body from `lines` (a lazy enumerable of
  iodata) as `mime`, read and sent by a process of its own in chunks of about 64 KiB
  (HTTP/1.1 chunked encoding), at the pace the client reads: the body is never held whole.
  Put the status and headers before it. A stream that breaks off (the file went away, the
  client left) is logged as `what` ended early, and the connection closed.
  """
  @spec stream(tuple(), charlist(), Enumerable.t(), String.t()) :: [tuple()]
  def stream(arg, mime, lines, what) do
    socket = NeptunusWeb.Endpoint.Yaws.arg(arg, :clisock)
    pid = spawn(fn -> stream_body(socket, lines, what) end)
    [{:streamcontent_from_pid, mime, pid}]
  end

  defp stream_body(socket, lines, what) do
    await_stream(
      socket,
      fn yaws ->
        case deliver(socket, lines) do
          :ok ->
            :yaws_api.stream_process_deliver_final_chunk(socket, [])
            :yaws_api.stream_process_end(socket, yaws)

          {:error, reason} ->
            Logger.warning("#{what} ended early: #{inspect(reason)}")
            :yaws_api.stream_process_end(:closed, yaws)
        end
      end,
      30_000
    )
  end

  defp deliver(socket, lines) do
    lines
    |> Stream.chunk_while(
      {[], 0},
      fn line, {acc, size} ->
        size = size + IO.iodata_length(line)

        if size >= @chunk_bytes,
          do: {:cont, Enum.reverse([line | acc]), {[], 0}},
          else: {:cont, {[line | acc], size}}
      end,
      fn
        {[], _} -> {:cont, {[], 0}}
        {acc, _} -> {:cont, Enum.reverse(acc), {[], 0}}
      end
    )
    |> Enum.reduce_while(:ok, fn chunk, :ok ->
      case :yaws_api.stream_process_deliver_chunk(socket, chunk) do
        :ok -> {:cont, :ok}
        {:error, reason} -> {:halt, {:error, reason}}
      end
    end)
  rescue
    # the file went away or broke between the two passes
    error in [File.Error, ErlangError] -> {:error, Exception.message(error)}
  end
end
