defmodule NeptunusWeb.Endpoint.Yaws do
  @moduledoc """
  What the modules yaws calls (`NeptunusWeb.API`, `NeptunusWeb.Socket`,
  `NeptunusWeb.CameraStream`, `NeptunusWeb.Endpoint.Guard`) share: yaws' records, extracted
  from its header (`erl_libs/yaws-*/include/yaws_api.hrl`), and helpers that read a request
  from them.

  ## Modules that read yaws' internals

  Two modules rely on what yaws does inside, which no interface promises and a new release
  may change silently: `NeptunusWeb.Endpoint.HeaderDeadline` reads the stacks and process
  dictionaries of yaws' connection processes, `NeptunusWeb.Endpoint.ConnectionLog` matches
  the text of one of yaws' log messages. Each names the yaws versions it was written for and
  checks the one this node runs when it starts (`supported/4`): on any other it refuses to
  start, and the endpoint with it, with a message that says what to check. (Records and
  `yaws_api` are yaws' interface: the records are read from the header of the yaws this
  node is built with.)
  """
  require Logger
  require Record

  @hrl Path.wildcard(Path.join([__DIR__, "../../../erl_libs/yaws-*/include/yaws_api.hrl"]))
       |> List.first() ||
         raise("yaws headers not found in erl_libs/: run `make setup`")

  @external_resource @hrl

  Record.defrecord(:arg, Record.extract(:arg, from: @hrl))
  Record.defrecord(:http_request, Record.extract(:http_request, from: @hrl))
  Record.defrecord(:headers, Record.extract(:headers, from: @hrl))
  Record.defrecord(:ws_state, Record.extract(:ws_state, from: @hrl))
  Record.defrecord(:rewrite_response, Record.extract(:rewrite_response, from: @hrl))

  @doc "The version of the yaws this node runs (`\"2.1.1\"`), or nil when none is loaded."
  @spec version() :: String.t() | nil
  def version do
    _ = Application.load(:yaws)

    case Application.spec(:yaws, :vsn) do
      nil -> nil
      vsn -> to_string(vsn)
    end
  end

  @doc """
  Whether `module`, which reads yaws' internals (`reads`: which ones) and was written for the
  yaws `versions`, may run on the yaws `running`: `:ok`, or the message that says why not.

      iex> alias NeptunusWeb.Endpoint.Yaws
      iex> Yaws.check_version(MyMod, ["2.1.1"], "its logs", "2.1.1")
      :ok
      iex> {:error, message} = Yaws.check_version(MyMod, ["2.1.1"], "its logs", "2.2.0")
      iex> message
      "MyMod reads yaws' internals (its logs) and was written for yaws 2.1.1; this node runs " <>
        "yaws 2.2.0. Check MyMod against yaws 2.2.0 and add that version to its " <>
        "@yaws_versions, or install yaws 2.1.1."
  """
  @spec check_version(module(), [String.t(), ...], String.t(), String.t() | nil) ::
          :ok | {:error, String.t()}
  def check_version(module, versions, reads, running) do
    if running in versions do
      :ok
    else
      name = inspect(module)
      written_for = Enum.join(versions, ", ")
      runs = if running, do: "yaws #{running}", else: "no yaws"

      {:error,
       "#{name} reads yaws' internals (#{reads}) and was written for yaws #{written_for}; " <>
         "this node runs #{runs}. Check #{name} against #{runs} and add that version to its " <>
         "@yaws_versions, or install yaws #{List.last(versions)}."}
    end
  end

  @doc """
  For the `init/1` of a process that reads yaws' internals (see "Modules that read yaws'
  internals"): `:ok` when the yaws this node runs is one that `module` (reading `reads`) was
  written for, one of `versions`; else `{:stop, {:unsupported_yaws, message}}`, the message
  logged as an error (`check_version/4`). `opts` are the process's options: `:yaws_version`
  names the version to check (default: `version/0`, the one running).
  """
  @spec supported(module(), [String.t(), ...], String.t(), keyword()) ::
          :ok | {:stop, {:unsupported_yaws, String.t()}}
  def supported(module, versions, reads, opts) do
    running = Keyword.get_lazy(opts, :yaws_version, &version/0)

    case check_version(module, versions, reads, running) do
      :ok ->
        :ok

      {:error, message} ->
        Logger.error(message)
        {:stop, {:unsupported_yaws, message}}
    end
  end

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
