defmodule NeptunusWeb.Yaws do
  @moduledoc false
  # yaws' records, extracted from its header (erl_libs/yaws-*/include/yaws_api.hrl).
  require Record

  @hrl Path.wildcard(Path.join([__DIR__, "../../erl_libs/yaws-*/include/yaws_api.hrl"]))
       |> List.first() ||
         raise("yaws headers not found in erl_libs/: run `make setup`")

  @external_resource @hrl

  Record.defrecord(:arg, Record.extract(:arg, from: @hrl))
  Record.defrecord(:http_request, Record.extract(:http_request, from: @hrl))
  Record.defrecord(:headers, Record.extract(:headers, from: @hrl))
  Record.defrecord(:ws_state, Record.extract(:ws_state, from: @hrl))

  # In the process of a `{:streamcontent_from_pid, mime, pid}` reply: waits for yaws to hand
  # over the socket and runs `fun.(yaws_pid)`; a HEAD request's stream is ended at once.
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
