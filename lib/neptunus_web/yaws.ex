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
end
