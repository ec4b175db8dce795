defmodule Neptunus.Settings.Rules do
  @moduledoc """
  What the settings store (`Neptunus.Settings`) accepts and how it lays its files out (pure).

  A **scope** is whose settings they are: `{:user, name}` (a person's: gamepad mapping,
  developer plots) or `{:vehicle, id}` (a vehicle's, the same on every device: camera
  rotation, tuning). The name or id is a non-empty UTF-8 string of at most
  #{64} bytes without control characters.

  A **key** is 1..64 characters of `A-Z a-z 0-9 . _ -` (e.g. `gamepad.mapping`), so keys read
  the same in URLs, JSON and logs.

  A **value** is anything JSON can say — `nil`, booleans, numbers, UTF-8 strings, lists and
  maps with string keys, nested — whose JSON text is at most `max_value_bytes/0` bytes; a
  scope holds at most `max_keys/0` keys. The limits keep one scope's file small (read whole,
  written whole) and keep a client from filling the vehicle computer's disk.

  One scope is one file, `<dir>/<kind>/<name as base64url>.json` (`path/2`): the name is
  encoded so that no name can reach outside the directory or collide with another by case or
  punctuation. The file holds the scope and its settings as JSON (`encode_file/2`,
  `decode_file/2`), so it can be read and repaired by hand.
  """

  alias Neptunus.JSON

  @type scope :: {:user, String.t()} | {:vehicle, String.t()}
  @type settings :: %{optional(String.t()) => term()}

  @max_name_bytes 64
  @max_value_bytes 16_384
  @max_keys 64

  @doc "The most bytes a value's JSON text may take."
  @spec max_value_bytes() :: pos_integer()
  def max_value_bytes, do: @max_value_bytes

  @doc "The most keys one scope may hold."
  @spec max_keys() :: pos_integer()
  def max_keys, do: @max_keys

  @doc """
  Checks a scope.

      iex> Neptunus.Settings.Rules.scope({:user, "alice"})
      :ok
      iex> Neptunus.Settings.Rules.scope({:user, ""})
      {:error, "a user name must be a non-empty string of at most 64 bytes without control characters"}
      iex> Neptunus.Settings.Rules.scope({:robot, "x"})
      {:error, "a scope must be {:user, name} or {:vehicle, id}, got {:robot, \\"x\\"}"}
  """
  @spec scope(term()) :: :ok | {:error, String.t()}
  def scope({kind, name}) when kind in [:user, :vehicle] do
    if name?(name),
      do: :ok,
      else:
        {:error,
         "a #{kind_text(kind)} must be a non-empty string of at most #{@max_name_bytes} bytes " <>
           "without control characters"}
  end

  def scope(other),
    do:
      {:error, "a scope must be {:user, name} or {:vehicle, id}, got #{inspect(other, limit: 5)}"}

  defp kind_text(:user), do: "user name"
  defp kind_text(:vehicle), do: "vehicle id"

  defp name?(name) do
    is_binary(name) and name != "" and byte_size(name) <= @max_name_bytes and
      String.valid?(name) and not String.match?(name, ~r/[\x00-\x1f\x7f]/)
  end

  @doc """
  Checks a key.

      iex> Neptunus.Settings.Rules.key("gamepad.mapping")
      :ok
      iex> Neptunus.Settings.Rules.key("../x")
      {:error, "a key must be 1..64 characters of A-Z a-z 0-9 . _ -, got \\"../x\\""}
  """
  @spec key(term()) :: :ok | {:error, String.t()}
  def key(key) when is_binary(key) do
    if String.match?(key, ~r/\A[A-Za-z0-9._-]{1,64}\z/) and key not in [".", ".."],
      do: :ok,
      else: {:error, "a key must be 1..64 characters of A-Z a-z 0-9 . _ -, got #{show(key)}"}
  end

  def key(other),
    do: {:error, "a key must be 1..64 characters of A-Z a-z 0-9 . _ -, got #{show(other)}"}

  @doc """
  Checks a value: JSON-able and at most `max_value_bytes/0` bytes of JSON.

      iex> Neptunus.Settings.Rules.value(%{"a" => [1, 2.5, nil, true, "x"]})
      :ok
      iex> Neptunus.Settings.Rules.value(%{a: 1})
      {:error, "a value must be JSON (null, booleans, numbers, strings, lists, objects with string keys): :a is not a string key"}
  """
  @spec value(term()) :: :ok | {:error, String.t()}
  def value(value) do
    with :ok <- json(value) do
      size = value |> JSON.encode!() |> byte_size()

      if size <= @max_value_bytes,
        do: :ok,
        else: {:error, "a value must be at most #{@max_value_bytes} bytes of JSON, got #{size}"}
    end
  end

  @json_error "a value must be JSON (null, booleans, numbers, strings, lists, objects with string keys)"

  defp json(v) when is_nil(v) or is_boolean(v) or is_number(v), do: :ok

  defp json(v) when is_binary(v) do
    if String.valid?(v), do: :ok, else: {:error, "#{@json_error}: a string is not UTF-8"}
  end

  defp json(list) when is_list(list) do
    if proper_list?(list),
      do: Enum.reduce_while(list, :ok, fn v, :ok -> halt_on_error(json(v)) end),
      else: {:error, "#{@json_error}: an improper list"}
  end

  defp json(map) when is_map(map) and not is_struct(map) do
    Enum.reduce_while(map, :ok, fn
      {k, v}, :ok when is_binary(k) ->
        if String.valid?(k),
          do: halt_on_error(json(v)),
          else: {:halt, {:error, "#{@json_error}: a key is not UTF-8"}}

      {k, _v}, :ok ->
        {:halt, {:error, "#{@json_error}: #{inspect(k, limit: 5)} is not a string key"}}
    end)
  end

  defp json(other), do: {:error, "#{@json_error}: #{inspect(other, limit: 5)} is not JSON"}

  defp halt_on_error(:ok), do: {:cont, :ok}
  defp halt_on_error(error), do: {:halt, error}

  defp proper_list?([]), do: true
  defp proper_list?([_ | tail]), do: proper_list?(tail)
  defp proper_list?(_), do: false

  @doc """
  What `put` does to a scope's `settings` (pure): the new settings, or why not (a bad key or
  value, or a new key beyond `max_keys/0`). Nothing changes on an error.
  """
  @spec put(settings(), term(), term()) :: {:ok, settings()} | {:error, String.t()}
  def put(settings, key, value) do
    with :ok <- key(key),
         :ok <- value(value) do
      if map_size(settings) >= @max_keys and not Map.has_key?(settings, key),
        do: {:error, "a scope holds at most #{@max_keys} settings: delete one first"},
        else: {:ok, Map.put(settings, key, value)}
    end
  end

  @doc """
  The file of `scope` under `dir`.

      iex> Neptunus.Settings.Rules.path("/s", {:user, "alice"})
      "/s/user/YWxpY2U.json"
      iex> Neptunus.Settings.Rules.path("/s", {:vehicle, "../x"})
      "/s/vehicle/Li4veA.json"
  """
  @spec path(Path.t(), scope()) :: Path.t()
  def path(dir, {kind, name}),
    do: Path.join([dir, Atom.to_string(kind), Base.url_encode64(name, padding: false) <> ".json"])

  @doc "The JSON text of `scope`'s file holding `settings`."
  @spec encode_file(scope(), settings()) :: binary()
  def encode_file({kind, name}, settings),
    do: JSON.encode!(%{Atom.to_string(kind) => name, "settings" => settings})

  @doc """
  Reads `scope`'s file text: its settings, or why it cannot be used (not JSON, not of this
  scope, a bad key or value). A file is all or nothing: one bad entry makes the whole file
  unusable, as a partly read file would silently lose settings.

      iex> Neptunus.Settings.Rules.decode_file(~s({"user":"a","settings":{"k":1}}), {:user, "a"})
      {:ok, %{"k" => 1}}
      iex> Neptunus.Settings.Rules.decode_file(~s({"user":"b","settings":{}}), {:user, "a"})
      {:error, "the file is not of user \\"a\\""}
  """
  @spec decode_file(binary(), scope()) :: {:ok, settings()} | {:error, String.t()}
  def decode_file(text, {kind, name} = scope) do
    kind_key = Atom.to_string(kind)

    case JSON.decode(text, copy_strings: true) do
      {:ok, %{^kind_key => ^name, "settings" => settings} = file}
      when is_map(settings) and map_size(file) == 2 ->
        if map_size(settings) > @max_keys do
          {:error, "the file holds #{map_size(settings)} settings, more than #{@max_keys}"}
        else
          settings
          |> Enum.reduce_while(:ok, fn {k, v}, :ok ->
            case with(:ok <- key(k), do: value(v)) do
              :ok -> {:cont, :ok}
              {:error, reason} -> {:halt, {:error, "setting #{show(k)}: #{reason}"}}
            end
          end)
          |> case do
            :ok -> {:ok, settings}
            error -> error
          end
        end

      {:ok, _other} ->
        {:error, "the file is not of #{kind} #{inspect(elem(scope, 1))}"}

      {:error, reason} ->
        {:error, reason}
    end
  end

  defp show(term) when is_binary(term) do
    if String.valid?(term), do: inspect(String.slice(term, 0, 60)), else: "a non-UTF-8 string"
  end

  defp show(term), do: inspect(term, limit: 5)
end
