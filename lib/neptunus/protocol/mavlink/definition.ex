defmodule Neptunus.Protocol.MAVLink.Definition do
  @moduledoc """
  Turns a message's XML declaration into the definition the codec uses
  (`Neptunus.Protocol.MAVLink.Messages` calls `build/1` at compile time): the fields, the
  wire order, the CRC_EXTRA byte and the payload lengths, as described there.
  """

  import Bitwise

  alias Neptunus.Protocol.MAVLink.CRC

  @type type ::
          :uint8
          | :int8
          | :uint16
          | :int16
          | :uint32
          | :int32
          | :uint64
          | :int64
          | :float
          | :double
          | :char
  @type field :: %{
          name: atom(),
          type: type(),
          length: nil | pos_integer(),
          extension: boolean(),
          c_type: String.t()
        }
  @type t :: %{
          id: non_neg_integer(),
          name: atom(),
          fields: [field()],
          wire: [field()],
          crc_extra: byte(),
          base_length: pos_integer(),
          full_length: pos_integer()
        }

  @typedoc "A declaration as copied from the XML: `{id, \"NAME\", [{\"type\", \"name\"} | :ext]}`."
  @type declaration :: {non_neg_integer(), String.t(), [{String.t(), String.t()} | :ext]}

  @types %{
    "uint8_t" => {:uint8, 1},
    "uint8_t_mavlink_version" => {:uint8, 1},
    "int8_t" => {:int8, 1},
    "char" => {:char, 1},
    "uint16_t" => {:uint16, 2},
    "int16_t" => {:int16, 2},
    "uint32_t" => {:uint32, 4},
    "int32_t" => {:int32, 4},
    "float" => {:float, 4},
    "uint64_t" => {:uint64, 8},
    "int64_t" => {:int64, 8},
    "double" => {:double, 8}
  }

  @doc "The size in bytes of one element of a type."
  @spec size(type()) :: 1 | 2 | 4 | 8
  def size(type) when type in [:uint8, :int8, :char], do: 1
  def size(type) when type in [:uint16, :int16], do: 2
  def size(type) when type in [:uint32, :int32, :float], do: 4
  def size(type) when type in [:uint64, :int64, :double], do: 8

  @doc """
  Builds a message definition from its XML declaration (`{id, "NAME", fields}` with each field
  `{"type", "name"}` and `:ext` where the extensions begin).
  """
  @spec build(declaration()) :: t()
  def build({id, name, declared}) do
    {fields, _} =
      Enum.map_reduce(declared, false, fn
        :ext, _ -> {nil, true}
        {type, field}, ext -> {parse_field(type, field, ext), ext}
      end)

    fields = Enum.reject(fields, &is_nil/1)
    {base, extensions} = Enum.split_with(fields, &(not &1.extension))
    # Enum.sort_by is stable: equal sizes keep their declaration order
    wire = Enum.sort_by(base, &size(&1.type), :desc) ++ extensions

    %{
      id: id,
      name: name |> String.downcase() |> String.to_atom(),
      fields: fields,
      wire: wire,
      crc_extra: crc_extra(name, base |> Enum.sort_by(&size(&1.type), :desc)),
      base_length: payload_length(base),
      full_length: payload_length(fields)
    }
  end

  defp parse_field(type, name, extension) do
    {element, length} =
      case Regex.run(~r/^([a-z0-9_]+)\[(\d+)\]$/, type) do
        [_, element, n] -> {element, String.to_integer(n)}
        nil -> {type, nil}
      end

    {atom_type, _size} = Map.fetch!(@types, element)

    %{
      name: String.to_atom(name),
      type: atom_type,
      length: length,
      extension: extension,
      # the element type as the CRC_EXTRA rule spells it
      c_type: if(element == "uint8_t_mavlink_version", do: "uint8_t", else: element)
    }
  end

  defp crc_extra(name, wire_base) do
    crc =
      Enum.reduce(wire_base, CRC.x25(name <> " "), fn field, crc ->
        crc = CRC.x25(field.c_type <> " " <> Atom.to_string(field.name) <> " ", crc)
        if field.length, do: CRC.x25(<<field.length>>, crc), else: crc
      end)

    bxor(crc &&& 0xFF, crc >>> 8)
  end

  defp payload_length(fields),
    do: Enum.reduce(fields, 0, fn f, acc -> acc + size(f.type) * (f.length || 1) end)
end
