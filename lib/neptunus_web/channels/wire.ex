defmodule NeptunusWeb.Channels.Wire do
  @moduledoc """
  Phoenix Channels v2 JSON frame codec (pure), on `Neptunus.JSON`.

  A v2 frame is a JSON text frame holding a five-element array:

      [join_ref, ref, topic, event, payload]

  `join_ref` and `ref` are strings or `null` (the official JS client sends
  strings; heartbeats and broadcasts use `null`), `topic` and `event` are
  non-empty strings and `payload` is a JSON object.

  ## Decoding

  `decode/1` never raises. It returns `{:ok, %Message{}}` or
  `{:error, reason, partial}`, where `reason` is a sentence a person can read
  and `partial` holds the `join_ref`, `ref` and `topic` that could be read
  from the frame (each `nil` when not), so the caller can still address an
  error reply:

      iex> {:ok, msg} = NeptunusWeb.Channels.Wire.decode(~s(["1","2","vehicle:a","thrust",{"surge":0.5}]))
      iex> {msg.join_ref, msg.ref, msg.topic, msg.event, msg.payload}
      {"1", "2", "vehicle:a", "thrust", %{"surge" => 0.5}}

      iex> NeptunusWeb.Channels.Wire.decode(~s(["1","2","vehicle:a","thrust","fast"]))
      {:error, "payload must be a JSON object", %{join_ref: "1", ref: "2", topic: "vehicle:a"}}

      iex> NeptunusWeb.Channels.Wire.decode(~s([1,2))
      {:error, "invalid JSON at byte 5: unexpected end of input", %{join_ref: nil, ref: nil, topic: nil}}

  Error reasons (byte positions are jiffy's: 1-based, pointing at or just
  before the offending byte, one past the end for truncated input):

    * `"empty frame"`
    * `"invalid JSON at byte N: <what>"`, `"invalid JSON: number out of range"` (from
      `Neptunus.JSON.decode/2`)
    * `"frame must be a JSON array [join_ref, ref, topic, event, payload]"`
    * `"frame must have 5 elements, got N"`
    * `"join_ref must be a string or null"`, `"ref must be a string or null"`
    * `"topic must be a non-empty string"`, `"event must be a non-empty string"`
    * `"payload must be a JSON object"`

  Integers are arbitrary precision, so very long numbers decode (slowly: a
  200 000-digit number takes about half a second). Callers must cap the
  frame size before decoding.

  ## Encoding

  Payloads are maps with atom or string keys; values may be `nil` (encoded
  as `null`), booleans, numbers, strings, atoms (encoded as strings), lists
  and nested maps. The encoders always return a binary and raise
  `ArgumentError` on terms JSON cannot express (tuples, pids, invalid UTF-8):

      iex> NeptunusWeb.Channels.Wire.encode_reply("1", "2", "vehicle:a", :ok, %{gain: nil})
      ~s(["1","2","vehicle:a","phx_reply",{"status":"ok","response":{"gain":null}}])

      iex> NeptunusWeb.Channels.Wire.encode_broadcast("vehicle:a", "telemetry", %{"depth" => 1.5})
      ~s([null,null,"vehicle:a","telemetry",{"depth":1.5}])

  Encode a broadcast once with `encode_broadcast/3` and send the same bytes
  to every subscriber.

  Structs are not special-cased by jiffy (they encode with a `"__struct__"`
  key): convert them to plain maps first. Charlists encode as integer arrays.
  """

  defmodule Message do
    @moduledoc "A decoded Phoenix Channels v2 frame."

    @enforce_keys [:topic, :event, :payload]
    defstruct [:join_ref, :ref, :topic, :event, :payload]

    @typedoc """
    * `join_ref` — ref of the `phx_join` that opened the channel (`nil` for
      messages outside a channel, e.g. heartbeats)
    * `ref` — ref of this push, echoed in the reply (`nil` for broadcasts)
    * `topic`, `event` — non-empty strings
    * `payload` — decoded JSON object, string keys
    """
    @type t :: %__MODULE__{
            join_ref: String.t() | nil,
            ref: String.t() | nil,
            topic: String.t(),
            event: String.t(),
            payload: map()
          }
  end

  @typedoc "Whatever addressing fields could be read from a rejected frame."
  @type partial :: %{join_ref: String.t() | nil, ref: String.t() | nil, topic: String.t() | nil}

  alias Neptunus.JSON

  @empty_partial %{join_ref: nil, ref: nil, topic: nil}

  @doc """
  Decodes a v2 text frame. Never raises; see the moduledoc for the reasons.
  """
  @spec decode(binary()) :: {:ok, Message.t()} | {:error, String.t(), partial()}
  def decode(""), do: {:error, "empty frame", @empty_partial}

  def decode(frame) when is_binary(frame) do
    # Frame fields (topics, refs) are often kept in process state: copy them
    # instead of keeping sub-binaries of the whole frame alive.
    case JSON.decode(frame, copy_strings: true) do
      {:ok, term} -> validate(term)
      {:error, reason} -> {:error, reason, @empty_partial}
    end
  end

  def decode(_frame), do: {:error, "frame must be a binary", @empty_partial}

  @doc """
  Encodes a v2 frame. `payload` is a map with atom or string keys.
  """
  @spec encode(String.t() | nil, String.t() | nil, String.t(), String.t(), map()) :: binary()
  def encode(join_ref, ref, topic, event, payload) when is_map(payload) do
    JSON.encode!([join_ref, ref, topic, event, payload])
  end

  @doc """
  Encodes a `phx_reply` answering the push `ref` on `topic`:
  `[join_ref, ref, topic, "phx_reply", {"status": "ok" | "error", "response": response}]`.
  """
  @spec encode_reply(String.t() | nil, String.t() | nil, String.t(), :ok | :error, map()) ::
          binary()
  def encode_reply(join_ref, ref, topic, status, response)
      when status in [:ok, :error] and is_map(response) do
    encode(join_ref, ref, topic, "phx_reply", %{status: status, response: response})
  end

  @doc """
  Encodes a broadcast `[null, null, topic, event, payload]`. The bytes do not
  depend on the subscriber: encode once, send to all.
  """
  @spec encode_broadcast(String.t(), String.t(), map()) :: binary()
  def encode_broadcast(topic, event, payload), do: encode(nil, nil, topic, event, payload)

  # Decoding

  defp validate([join_ref, ref, topic, event, payload] = frame) do
    partial = partial(frame)

    cond do
      not ref?(join_ref) ->
        {:error, "join_ref must be a string or null", partial}

      not ref?(ref) ->
        {:error, "ref must be a string or null", partial}

      not name?(topic) ->
        {:error, "topic must be a non-empty string", partial}

      not name?(event) ->
        {:error, "event must be a non-empty string", partial}

      not is_map(payload) ->
        {:error, "payload must be a JSON object", partial}

      true ->
        {:ok,
         %Message{join_ref: join_ref, ref: ref, topic: topic, event: event, payload: payload}}
    end
  end

  defp validate(frame) when is_list(frame),
    do: {:error, "frame must have 5 elements, got #{length(frame)}", partial(frame)}

  defp validate(_other),
    do:
      {:error, "frame must be a JSON array [join_ref, ref, topic, event, payload]",
       @empty_partial}

  # Reads the addressing fields that are well-typed, even from a frame of the
  # wrong length, so an error reply can reach the sender.
  defp partial(frame) do
    %{
      join_ref: frame |> Enum.at(0) |> keep_if(&ref?/1),
      ref: frame |> Enum.at(1) |> keep_if(&ref?/1),
      topic: frame |> Enum.at(2) |> keep_if(&name?/1)
    }
  end

  defp keep_if(value, valid?), do: if(valid?.(value), do: value, else: nil)

  defp ref?(value), do: is_nil(value) or is_binary(value)
  defp name?(value), do: is_binary(value) and value != ""
end
