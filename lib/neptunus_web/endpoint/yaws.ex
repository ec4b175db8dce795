defmodule NeptunusWeb.Endpoint.Yaws do
  @moduledoc """
  What the modules yaws calls (`NeptunusWeb.API`, `NeptunusWeb.Socket`,
  `NeptunusWeb.CameraStream`, `NeptunusWeb.Endpoint.Guard`) share: yaws' records, extracted
  from its header (`erl_libs/yaws-*/include/yaws_api.hrl`), and helpers that read a request
  from them.
  """
  require Record

  @hrl Path.wildcard(Path.join([__DIR__, "../../../erl_libs/yaws-*/include/yaws_api.hrl"]))
       |> List.first() ||
         raise("yaws headers not found in erl_libs/: run `make setup`")

  @external_resource @hrl

  Record.defrecord(:arg, Record.extract(:arg, from: @hrl))
  Record.defrecord(:http_request, Record.extract(:http_request, from: @hrl))
  Record.defrecord(:headers, Record.extract(:headers, from: @hrl))
  Record.defrecord(:ws_state, Record.extract(:ws_state, from: @hrl))

  @doc """
  The value of the header `name` (lower case) that yaws does not parse into a field of its
  `#headers{}` record (e.g. `origin`), or nil. Fields yaws parses (`host`, `authorization`,
  …) are read with `headers/2`.
  """
  @spec header(tuple(), String.t()) :: String.t() | nil
  def header(headers, name) when is_binary(name) do
    Enum.find_value(headers(headers, :other), fn
      {:http_header, _, key, _, value} ->
        if String.downcase(to_string(key)) == name, do: to_string(value)

      _ ->
        nil
    end)
  end

  @doc """
  The request's query string as a map (`URI.decode_query/1`: a later duplicate wins,
  malformed escapes are kept as they are); an empty map without a query string.
  """
  @spec query(tuple()) :: %{optional(String.t()) => String.t()}
  def query(arg), do: decode_query(arg(arg, :querydata))

  @doc false
  # the query string as yaws hands it over (a charlist, or :undefined)
  @spec decode_query(charlist() | String.t() | :undefined) :: %{
          optional(String.t()) => String.t()
        }
  def decode_query(:undefined), do: %{}

  def decode_query(query) when is_list(query) or is_binary(query) do
    URI.decode_query(to_string(query))
  rescue
    _ -> %{}
  end

  def decode_query(_other), do: %{}

  @doc "A text field of a yaws record (a charlist) as a string; nil for `:undefined`."
  @spec text(charlist() | String.t() | :undefined) :: String.t() | nil
  def text(value) when is_list(value) or is_binary(value), do: to_string(value)
  def text(_undefined), do: nil

  # In the process of a `{:streamcontent_from_pid, mime, pid}` reply: waits for yaws to hand
  # over the socket and runs `fun.(yaws_pid)`; a HEAD request's stream is ended at once.
  @doc false
  @spec await_stream(term(), (pid() -> term()), timeout()) :: term()
  def await_stream(socket, fun, timeout) do
    receive do
      {:ok, yaws} -> fun.(yaws)
      {:discard, yaws} -> :yaws_api.stream_process_end(socket, yaws)
    after
      timeout -> :ok
    end
  end
end
