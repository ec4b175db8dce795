defmodule NeptunusWeb.WireSchema.JSONSchema do
  @moduledoc """
  A payload type of the wire schema (`NeptunusWeb.WireSchema`) as a JSON Schema, for the
  MCAP export's channels (`Neptunus.Dive.Export`): Foxglove reads a channel's fields, types
  and descriptions from it. Every definition is written in place (no `$ref`: the telemetry's
  types nest, they do not recurse), each field with its doc and unit as its description, a
  nullable field as `anyOf` with null. No field is required: a dive recorded by an older
  version may lack the newer ones.
  """

  alias NeptunusWeb.WireSchema

  @doc """
  The JSON Schema of the named payload type, titled `title`.

      iex> schema = NeptunusWeb.WireSchema.JSONSchema.schema(:measurement, "neptunus.Measurement")
      iex> schema.properties.depth
      %{anyOf: [%{type: "number"}, %{type: "null"}], description: "positive down (m)"}
  """
  @spec schema(atom(), String.t()) :: map()
  def schema(name, title), do: Map.put(type(name), :title, title)

  defp type(:number), do: %{type: "number"}
  defp type(:integer), do: %{type: "integer"}
  defp type(:string), do: %{type: "string"}
  defp type(:boolean), do: %{type: "boolean"}
  defp type({:enum, values}), do: %{enum: values}
  defp type({:list, t}), do: %{type: "array", items: type(t)}
  defp type({:map, t}), do: %{type: "object", additionalProperties: type(t)}
  defp type({:one_of, types}), do: %{anyOf: Enum.map(types, &type/1)}
  defp type({:or_null, t}), do: %{anyOf: [type(t), %{type: "null"}]}

  defp type(name) when is_atom(name) do
    case WireSchema.definition(name) do
      %{kind: :object, doc: doc, fields: fields} ->
        %{
          type: "object",
          description: doc,
          properties: Map.new(fields, &{&1.name, field(&1)})
        }

      %{kind: :enum, doc: doc, values: values} ->
        %{enum: values, description: doc}

      %{kind: :union, doc: doc, types: types} ->
        %{anyOf: Enum.map(types, &type/1), description: doc}
    end
  end

  defp field(field) do
    schema = type(field.type)
    schema = if field.null, do: %{anyOf: [schema, %{type: "null"}]}, else: schema

    description =
      [field.doc, field.unit && "(#{field.unit})"]
      |> Enum.reject(&(&1 in [nil, ""]))
      |> Enum.join(" ")

    if description == "", do: schema, else: Map.put(schema, :description, description)
  end
end
