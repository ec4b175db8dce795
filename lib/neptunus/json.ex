defmodule Neptunus.JSON do
  @moduledoc """
  JSON encoding and decoding (pure, on jiffy), with errors a person can read.

  Every JSON text the node reads or writes goes through here: vehicle parameters, scenarios,
  recordings, the HTTP API's bodies and answers, login tokens, and the payloads of the
  WebSocket frames (`NeptunusWeb.Channels.Wire` builds the frames on top of this module).

  ## Decoding

  `decode/1` never raises. Objects become maps with string keys, `null` becomes `nil`;
  integers are arbitrary precision (a very long number decodes slowly: callers cap the input
  size before decoding).

      iex> Neptunus.JSON.decode(~s({"a": [1, null]}))
      {:ok, %{"a" => [1, nil]}}

      iex> Neptunus.JSON.decode(~s({"a": }))
      {:error, "invalid JSON at byte 7: invalid JSON"}

  Error reasons (byte positions are jiffy's: 1-based, pointing at or just before the
  offending byte, one past the end for truncated input):

    * `"empty JSON input"`, `"JSON input must be a binary"`
    * `"invalid JSON at byte N: <what>"`, e.g. `unexpected end of input`,
      `invalid string (bad escape or invalid UTF-8)`, `unexpected data after the JSON value`
    * `"invalid JSON: number out of range"`

  ## Encoding

  `encode!/1` takes `nil` (encoded as `null`), booleans, numbers, strings, atoms (encoded as
  strings), lists and maps with atom or string keys, nested. It returns a binary and raises
  `ArgumentError` on terms JSON cannot express (tuples, pids, invalid UTF-8):

      iex> Neptunus.JSON.encode!(%{ok: true, items: [1, nil, "x"]})
      ~s({"ok":true,"items":[1,null,"x"]})

  Structs are not special-cased by jiffy (they encode with a `"__struct__"` key): convert
  them to plain maps first. Charlists encode as integer arrays.
  """

  @decode_opts [:return_maps, {:null_term, nil}]
  @encode_opts [:use_nil]

  @typedoc """
  Decoding options: `copy_strings: true` copies the decoded strings out of the input
  instead of keeping sub-binaries of it alive (for values kept in process state).
  """
  @type decode_opt :: {:copy_strings, boolean()}

  @doc "Decodes JSON text. Never raises; see the moduledoc for the reasons."
  @spec decode(binary(), [decode_opt()]) :: {:ok, term()} | {:error, String.t()}
  def decode(json, opts \\ [])
  def decode("", _opts), do: {:error, "empty JSON input"}

  def decode(json, opts) when is_binary(json) and is_list(opts) do
    jiffy_opts =
      if Keyword.get(opts, :copy_strings, false),
        do: [:copy_strings | @decode_opts],
        else: @decode_opts

    {:ok, :jiffy.decode(json, jiffy_opts)}
  catch
    _kind, reason -> {:error, decode_error(reason)}
  end

  def decode(_json, _opts), do: {:error, "JSON input must be a binary"}

  @doc """
  Encodes any JSON-expressible term to a binary (`nil` → `null`). Raises `ArgumentError` on
  terms JSON cannot express.
  """
  @spec encode!(term()) :: binary()
  def encode!(term) do
    term |> :jiffy.encode(@encode_opts) |> IO.iodata_to_binary()
  catch
    kind, reason ->
      raise ArgumentError,
            "cannot encode as JSON: #{encode_error(kind, reason)} in #{inspect(term, limit: 20)}"
  end

  defp decode_error({pos, what}) when is_integer(pos) and is_atom(what),
    do: "invalid JSON at byte #{pos}: #{describe(what)}"

  defp decode_error({:range, _}), do: "invalid JSON: number out of range"
  defp decode_error(_other), do: "invalid JSON"

  defp describe(:truncated_json), do: "unexpected end of input"
  defp describe(:invalid_trailing_data), do: "unexpected data after the JSON value"
  defp describe(:invalid_string), do: "invalid string (bad escape or invalid UTF-8)"
  defp describe(:invalid_number), do: "invalid number"
  defp describe(:invalid_literal), do: "invalid literal (expected true, false or null)"
  defp describe(:invalid_json), do: "invalid JSON"
  defp describe(other), do: other |> Atom.to_string() |> String.replace("_", " ")

  defp encode_error(:error, {:invalid_string, bin}), do: "invalid UTF-8 string #{inspect(bin)}"
  defp encode_error(:error, {:invalid_ejson, term}), do: "unsupported term #{inspect(term)}"

  defp encode_error(:error, {:invalid_object_member_key, key}),
    do: "unsupported object key #{inspect(key)}"

  defp encode_error(kind, reason), do: Exception.format_banner(kind, reason)
end
