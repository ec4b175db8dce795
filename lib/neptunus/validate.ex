defmodule Neptunus.Validate do
  @moduledoc """
  Checks on untrusted JSON-decoded data (string keys) whose errors name the field: the one
  validation vocabulary of the node, for control commands (`Neptunus.Control.Command`), the
  vehicle parameter files (`Neptunus.Dynamics.Params`), scenarios (`Neptunus.Scenario`) and
  the live simulator's commands (`Neptunus.Sim.Live`). Pure.

  A field is named by its path from the document root, e.g. `duration`,
  `events[2].thrust.surge`, `damping.linear`. Error messages:

    * `missing field: PATH`
    * `unknown field: PATH (expected one of: a, b, c)`
    * `PATH must be an object, got …`
    * `PATH must be a number, got …`, `PATH must be a number in [0, 1], got …`,
      `PATH must be a number > 0, got …`, `PATH must be a number >= 0, got …`,
      `PATH must be a number in (0, 1], got …`
    * `PATH must be a list of N numbers, got …`
    * `PATH must be true or false, got …`, `PATH must be a string, got …`,
      `PATH must be an integer, got …`

  Values are shown as JSON (cut at 60 characters).

      iex> Neptunus.Validate.number(2, "events[0].gain", min: 0, max: 1)
      {:error, "events[0].gain must be a number in [0, 1], got 2"}

      iex> Neptunus.Validate.object(%{"t" => 1, "x" => 2}, "events[3]", ["t"], ["gain"])
      {:error, "unknown field: events[3].x (expected one of: gain, t)"}
  """

  @type path :: String.t()
  @type error :: {:error, String.t()}

  @doc "The path of `key` inside `path` (`\"\"` is the root); integers index lists."
  @spec join(path(), String.t() | non_neg_integer()) :: path()
  def join("", key) when is_binary(key), do: key
  def join(path, key) when is_binary(key), do: path <> "." <> key
  def join(path, index) when is_integer(index), do: "#{path}[#{index}]"

  @doc """
  `value` must be a map whose keys are all in `required ++ optional` and include every key of
  `required`. Unknown keys are reported first (the first in sorted order), then missing ones
  in the order given.
  """
  @spec object(term(), path(), [String.t()], [String.t()]) :: :ok | error()
  def object(value, path, required, optional \\ [])

  def object(value, path, required, optional) when is_map(value) do
    allowed = required ++ optional

    case value |> Map.keys() |> Enum.reject(&(&1 in allowed)) |> Enum.sort() do
      [key | _] when allowed == [] ->
        {:error, "unknown field: #{join(path, to_string(key))} (no fields expected)"}

      [key | _] ->
        {:error,
         "unknown field: #{join(path, to_string(key))} " <>
           "(expected one of: #{allowed |> Enum.sort() |> Enum.join(", ")})"}

      [] ->
        case Enum.find(required, &(not Map.has_key?(value, &1))) do
          nil -> :ok
          key -> {:error, "missing field: #{join(path, key)}"}
        end
    end
  end

  def object(value, path, _required, _optional), do: must(path, "be an object", value)

  @doc """
  A number, returned as a float. Options: `:min`, `:max` (inclusive), `:greater_than`
  (exclusive lower bound).
  """
  @spec number(term(), path(), keyword()) :: {:ok, float()} | error()
  def number(value, path, opts \\ [])

  def number(value, path, opts) when is_number(value) do
    min = Keyword.get(opts, :min)
    max = Keyword.get(opts, :max)
    gt = Keyword.get(opts, :greater_than)

    if (gt != nil and not (value > gt)) or (min != nil and value < min) or
         (max != nil and value > max),
       do: must(path, "be #{number_kind(opts)}", value),
       else: {:ok, value * 1.0 + 0.0}
  end

  def number(value, path, opts), do: must(path, "be #{number_kind(opts)}", value)

  defp number_kind(opts) do
    case {Keyword.get(opts, :greater_than), Keyword.get(opts, :min), Keyword.get(opts, :max)} do
      {nil, nil, nil} -> "a number"
      {nil, min, nil} -> "a number >= #{fmt(min)}"
      {nil, nil, max} -> "a number <= #{fmt(max)}"
      {nil, min, max} -> "a number in [#{fmt(min)}, #{fmt(max)}]"
      {gt, _, nil} -> "a number > #{fmt(gt)}"
      {gt, _, max} -> "a number in (#{fmt(gt)}, #{fmt(max)}]"
    end
  end

  @doc """
  Applies `fun.(item, index)` to each item in order and collects the `{:ok, value}` results,
  stopping at the first error, which is returned as it is.

      iex> Neptunus.Validate.map_ok([1, 2], fn x, i -> {:ok, x + i} end)
      {:ok, [1, 3]}
      iex> Neptunus.Validate.map_ok([1, :x, :y], fn x, _ -> if is_integer(x), do: {:ok, x}, else: {:error, x} end)
      {:error, :x}
  """
  @spec map_ok(Enumerable.t(), (term(), non_neg_integer() -> {:ok, term()} | term())) ::
          {:ok, list()} | term()
  def map_ok(items, fun) do
    items
    |> Enum.with_index()
    |> Enum.reduce_while({:ok, []}, fn {item, i}, {:ok, acc} ->
      case fun.(item, i) do
        {:ok, value} -> {:cont, {:ok, [value | acc]}}
        error -> {:halt, error}
      end
    end)
    |> case do
      {:ok, acc} -> {:ok, Enum.reverse(acc)}
      error -> error
    end
  end

  @doc "A list of exactly `n` numbers, returned as floats. `opts` apply to each (see `number/3`)."
  @spec vector(term(), path(), pos_integer(), keyword()) :: {:ok, [float()]} | error()
  def vector(value, path, n, opts \\ [])

  def vector(value, path, n, opts) when is_list(value) and length(value) == n do
    map_ok(value, fn x, i -> number(x, join(path, i), opts) end)
  end

  def vector(value, path, n, _opts), do: must(path, "be a list of #{n} numbers", value)

  @doc "An `rows`×`cols` matrix (list of rows) of numbers, returned as floats."
  @spec matrix(term(), path(), pos_integer(), pos_integer()) :: {:ok, [[float()]]} | error()
  def matrix(value, path, rows, cols) when is_list(value) and length(value) == rows do
    map_ok(value, fn row, i -> vector(row, join(path, i), cols) end)
  end

  def matrix(value, path, rows, cols),
    do: must(path, "be a #{rows}x#{cols} matrix (a list of #{rows} rows)", value)

  @doc "A boolean."
  @spec boolean(term(), path()) :: {:ok, boolean()} | error()
  def boolean(value, _path) when is_boolean(value), do: {:ok, value}
  def boolean(value, path), do: must(path, "be true or false", value)

  @doc "A string."
  @spec string(term(), path()) :: {:ok, String.t()} | error()
  def string(value, _path) when is_binary(value), do: {:ok, value}
  def string(value, path), do: must(path, "be a string", value)

  @doc "An integer (JSON numbers without a fraction)."
  @spec integer(term(), path()) :: {:ok, integer()} | error()
  def integer(value, _path) when is_integer(value), do: {:ok, value}
  def integer(value, path), do: must(path, "be an integer", value)

  @doc "Fetches an optional field: `default` when absent, else `check.(value, path)`."
  @spec optional(map(), path(), String.t(), term(), (term(), path() -> {:ok, term()} | error())) ::
          {:ok, term()} | error()
  def optional(map, path, key, default, check) do
    case Map.fetch(map, key) do
      {:ok, value} -> check.(value, join(path, key))
      :error -> {:ok, default}
    end
  end

  @doc "Fetches a required field (the caller has checked it is present with `object/4`)."
  @spec required(map(), path(), String.t(), (term(), path() -> {:ok, term()} | error())) ::
          {:ok, term()} | error()
  def required(map, path, key, check) do
    case Map.fetch(map, key) do
      {:ok, value} -> check.(value, join(path, key))
      :error -> {:error, "missing field: #{join(path, key)}"}
    end
  end

  @doc "A value shown as JSON in an error message, cut at 60 characters."
  @spec show(term()) :: String.t()
  def show(value) do
    text =
      try do
        Neptunus.JSON.encode!(value)
      rescue
        ArgumentError -> inspect(value)
      end

    if String.length(text) > 60, do: String.slice(text, 0, 57) <> "...", else: text
  end

  defp must(path, what, value), do: {:error, "#{name(path)} must #{what}, got #{show(value)}"}

  defp name(""), do: "the document"
  defp name(path), do: path

  defp fmt(x) when is_integer(x), do: Integer.to_string(x)

  defp fmt(x) when is_float(x) do
    if x == Float.round(x) and abs(x) < 1.0e15,
      do: x |> trunc() |> Integer.to_string(),
      else: :erlang.float_to_binary(x, [:short])
  end

  @doc "A file's contents, or a readable error (`cannot read: no such file or directory`)."
  @spec read_file(Path.t()) :: {:ok, binary()} | {:error, String.t()}
  def read_file(file) do
    case File.read(file) do
      {:ok, data} -> {:ok, data}
      {:error, reason} -> {:error, "cannot read: #{:file.format_error(reason)}"}
    end
  end
end
