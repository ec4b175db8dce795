defmodule NeptunusWeb.Test.Video do
  @moduledoc """
  The video WebSocket (`/video/<id>/websocket`) from a test: connecting, and reading its
  text messages (JSON, decoded) and frames (`Neptunus.Camera.Frame.parse/1`).
  The receive helpers run in the owner of the client (the test) and raise on timeout.
  """
  import ExUnit.Assertions

  alias Neptunus.Camera.Frame
  alias Neptunus.Test.Patience
  alias NeptunusWeb.Test.{Wire, WSClient}

  @doc "Connects to vehicle `id`'s video; `opts` as `WSClient.connect/3` (`:query`: a map)."
  @spec connect(String.t(), keyword()) :: {:ok, pid()} | {:error, term()}
  def connect(id, opts \\ []) do
    query =
      case Keyword.get(opts, :query, %{}) do
        empty when map_size(empty) == 0 -> ""
        query -> "?" <> URI.encode_query(query)
      end

    WSClient.connect(Wire.port(), "/video/#{URI.encode(id)}/websocket" <> query, opts)
  end

  @doc """
  The next message: `{:text, map}` or `{:frame, parsed}`; raises when the connection closes
  or nothing comes within `timeout` ms.
  """
  @spec next(pid(), timeout()) :: {:text, map()} | {:frame, map()}
  def next(ws, timeout \\ Patience.ms()) do
    receive do
      {:ws, ^ws, {:text, json}} ->
        {:ok, message} = Neptunus.JSON.decode(json)
        {:text, message}

      {:ws, ^ws, {:binary, data}} ->
        {:ok, frame} = Frame.parse(data)
        {:frame, frame}

      {:ws, ^ws, {:close, code, reason}} ->
        flunk("the video socket closed: #{code} #{reason}")

      {:ws, ^ws, :closed} ->
        flunk("the video socket closed")
    after
      timeout -> flunk("no video message within #{timeout} ms")
    end
  end

  @doc "Reads messages until `fun` returns a truthy value for one; returns `{it, skipped}`."
  @spec until(pid(), (term() -> term()), timeout()) :: {term(), [term()]}
  def until(ws, fun, timeout \\ Patience.ms()) do
    deadline = System.monotonic_time(:millisecond) + timeout
    until(ws, fun, deadline, [])
  end

  defp until(ws, fun, deadline, acc) do
    message = next(ws, max(deadline - System.monotonic_time(:millisecond), 0))

    if fun.(message),
      do: {message, Enum.reverse(acc)},
      else: until(ws, fun, deadline, [message | acc])
  end

  @doc "The next `n` frames (text messages between them are returned apart)."
  @spec frames(pid(), pos_integer(), timeout()) :: {[map()], [map()]}
  def frames(ws, n, timeout \\ Patience.ms()) do
    Enum.reduce(1..n, {[], []}, fn _, {frames, texts} ->
      {{:frame, frame}, others} = until(ws, &match?({:frame, _}, &1), timeout)
      {[frame | frames], texts ++ for({:text, t} <- others, do: t)}
    end)
    |> then(fn {frames, texts} -> {Enum.reverse(frames), texts} end)
  end
end
