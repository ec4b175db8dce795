defmodule NeptunusWeb.WireSchema.Check do
  @moduledoc """
  Checks a payload against `NeptunusWeb.WireSchema`, strictly: every field the schema
  requires is there (absent only if `optional`), null only if `null: true`, of its type, and
  no field the schema does not name (unless the object is `open`). `essential` plays no part
  here: it is how a page reads a payload, not what a server may send.

  With `decodable: true` it checks what a page needs instead (the JS fake server, which
  implements a part of the contract, is held to that): the fields that are not `essential`
  may be absent or null; what is there must still be of its type, and named in the schema.

  It checks JSON as a client receives it (string keys, `nil` for null): `check_term/2`
  encodes a server term as the server does (`Neptunus.JSON`) and decodes it first. For the
  conformance tests; nothing on the server's path runs it.

      iex> NeptunusWeb.WireSchema.Check.check(:motion_command, %{"surge" => 1, "heave" => 0, "yaw" => 0})
      :ok
      iex> NeptunusWeb.WireSchema.Check.check(:motion_command, %{"surge" => "1", "heave" => 0, "roll" => 0})
      {:error, ["surge: expected number, got \\"1\\"", "yaw: missing", "roll: not in the schema"]}
  """

  alias NeptunusWeb.WireSchema

  @doc """
  `:ok`, or `{:error, problems}`: each a path and what is wrong there. Option
  `decodable: true`: see the moduledoc.
  """
  @spec check(WireSchema.type(), term(), keyword()) :: :ok | {:error, [String.t()]}
  def check(type, value, opts \\ []) do
    case problems(type, value, [], Keyword.get(opts, :decodable, false)) do
      [] -> :ok
      problems -> {:error, problems}
    end
  end

  @doc "`check/2` of a server term (atom keys, atoms), as JSON would carry it."
  @spec check_term(WireSchema.type(), term()) :: :ok | {:error, [String.t()]}
  def check_term(type, term) do
    {:ok, json} = term |> Neptunus.JSON.encode!() |> Neptunus.JSON.decode()
    check(type, json)
  end

  defp problems(:number, v, _path, _decodable) when is_number(v), do: []
  defp problems(:integer, v, _path, _decodable) when is_integer(v), do: []
  defp problems(:string, v, _path, _decodable) when is_binary(v), do: []
  defp problems(:boolean, v, _path, _decodable) when is_boolean(v), do: []

  defp problems(type, v, path, _decodable) when type in [:number, :integer, :string, :boolean],
    do: [problem(path, "expected #{type}, got #{show(v)}")]

  defp problems({:enum, values} = type, v, path, _decodable) do
    if v in values, do: [], else: [problem(path, "expected #{describe(type)}, got #{show(v)}")]
  end

  defp problems({:or_null, _type}, nil, _path, _decodable), do: []
  defp problems({:or_null, type}, v, path, decodable), do: problems(type, v, path, decodable)

  defp problems({:list, type}, v, path, decodable) when is_list(v) do
    v
    |> Enum.with_index()
    |> Enum.flat_map(fn {e, i} -> problems(type, e, [i | path], decodable) end)
  end

  defp problems({:map, type}, v, path, decodable) when is_map(v) do
    v |> Enum.sort() |> Enum.flat_map(fn {k, e} -> problems(type, e, [k | path], decodable) end)
  end

  defp problems({:one_of, types}, v, path, decodable) do
    results = Enum.map(types, &problems(&1, v, path, decodable))

    if Enum.any?(results, &(&1 == [])) do
      []
    else
      [problem(path, "fits none of #{Enum.map_join(types, ", ", &describe/1)}: #{show(v)}")]
    end
  end

  defp problems({kind, _} = type, v, path, _decodable) when kind in [:list, :map],
    do: [problem(path, "expected #{describe(type)}, got #{show(v)}")]

  defp problems(name, v, path, decodable) when is_atom(name) do
    case WireSchema.definition(name) do
      %{kind: :enum, values: values} -> problems({:enum, values}, v, path, decodable)
      %{kind: :union, types: types} -> problems({:one_of, types}, v, path, decodable)
      %{kind: :object} = object -> object_problems(object, v, path, decodable)
    end
  end

  defp object_problems(object, v, path, decodable) when is_map(v) do
    named =
      Enum.flat_map(object.fields, fn field ->
        key = Atom.to_string(field.name)
        at = [key | path]

        lenient = decodable and not field.essential

        case Map.fetch(v, key) do
          :error -> if field.optional or lenient, do: [], else: [problem(at, "missing")]
          {:ok, nil} -> if field.null or lenient, do: [], else: [problem(at, "null")]
          {:ok, value} -> problems(field.type, value, at, decodable)
        end
      end)

    known = MapSet.new(object.fields, &Atom.to_string(&1.name))

    unknown =
      if object.open,
        do: [],
        else:
          for(
            k <- v |> Map.keys() |> Enum.sort(),
            k not in known,
            do: problem([k | path], "not in the schema")
          )

    named ++ unknown
  end

  defp object_problems(object, v, path, _decodable),
    do: [problem(path, "expected #{object.name} (an object), got #{show(v)}")]

  defp problem([], what), do: what

  defp problem(path, what) do
    at =
      path
      |> Enum.reverse()
      |> Enum.map_join("", fn
        i when is_integer(i) -> "[#{i}]"
        k -> ".#{k}"
      end)
      |> String.trim_leading(".")

    "#{at}: #{what}"
  end

  defp describe({:enum, values}), do: Enum.map_join(values, " | ", &inspect/1)
  defp describe({:list, type}), do: "[#{describe(type)}]"
  defp describe({:map, type}), do: "{string: #{describe(type)}}"
  defp describe({:one_of, types}), do: Enum.map_join(types, " | ", &describe/1)
  defp describe({:or_null, type}), do: "#{describe(type)} | null"
  defp describe(name) when is_atom(name), do: Atom.to_string(name)

  defp show(v) do
    text = v |> Neptunus.JSON.encode!() |> IO.iodata_to_binary()
    if byte_size(text) > 80, do: binary_part(text, 0, 77) <> "...", else: text
  end
end
