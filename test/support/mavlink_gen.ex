defmodule Neptunus.Test.MAVLinkGen do
  @moduledoc """
  PropEr generators for MAVLink messages (`Neptunus.Protocol.MAVLink`): any defined message
  with values over each field's whole type range (floats that a float32 holds exactly, NaN and
  the infinities now and then; strings of non-NUL bytes up to their length; arrays of their
  exact length), headers, protocol versions; and what a receiver gets for fields sent as
  MAVLink 1 (no extensions: zero).
  """

  import Neptunus.Test.Properties, only: [bind: 2]

  alias Neptunus.Protocol.MAVLink.Messages

  @doc "`{name, fields}` of any defined message."
  @spec message() :: term()
  def message do
    :proper_types.oneof(for definition <- Messages.all(), do: message(definition.name))
  end

  @doc "`{name, fields}` of the given message."
  @spec message(atom()) :: term()
  def message(name) do
    definition = Messages.get(name)
    fields = for field <- definition.fields, do: {field.name, field(field)}
    {definition.name, bind(fields, &Map.new/1)}
  end

  @doc "A header `%{system, component, seq}`."
  @spec header() :: term()
  def header do
    bind(
      {:proper_types.integer(0, 255), :proper_types.integer(0, 255),
       :proper_types.integer(0, 255)},
      fn {system, component, seq} -> %{system: system, component: component, seq: seq} end
    )
  end

  @doc "1 or 2."
  @spec version() :: term()
  def version, do: :proper_types.oneof([1, 2])

  @doc """
  `{{name, fields}, header, version}`: any defined message, a header, and a protocol version
  that can carry it (MAVLink 1 only for ids below 256).
  """
  @spec framed() :: term()
  def framed do
    bind({message(), header(), version()}, fn {{name, _} = message, header, version} ->
      {message, header, if(Messages.get(name).id > 255, do: 2, else: version)}
    end)
  end

  @doc "The fields a receiver decodes from `fields` sent with `version`."
  @spec as_received(atom(), map(), 1 | 2) :: map()
  def as_received(_name, fields, 2), do: fields

  def as_received(name, fields, 1) do
    for field <- Messages.get(name).fields, into: %{} do
      {field.name, if(field.extension, do: zero(field), else: fields[field.name])}
    end
  end

  defp zero(%{type: :char}), do: ""
  defp zero(%{type: type, length: nil}) when type in [:float, :double], do: 0.0
  defp zero(%{length: nil}), do: 0
  defp zero(%{length: n} = field), do: List.duplicate(zero(%{field | length: nil}), n)

  defp field(%{type: :char, length: n}) do
    bind(:proper_types.list(:proper_types.integer(1, 255)), fn bytes ->
      bytes |> Enum.take(n) |> :erlang.list_to_binary()
    end)
  end

  defp field(%{type: type, length: nil}), do: value(type)
  defp field(%{type: type, length: n}), do: List.duplicate(value(type), n)

  defp value(:uint8), do: :proper_types.integer(0, 0xFF)
  defp value(:int8), do: :proper_types.integer(-0x80, 0x7F)
  defp value(:uint16), do: :proper_types.integer(0, 0xFFFF)
  defp value(:int16), do: :proper_types.integer(-0x8000, 0x7FFF)
  defp value(:uint32), do: :proper_types.integer(0, 0xFFFFFFFF)
  defp value(:int32), do: :proper_types.integer(-0x80000000, 0x7FFFFFFF)
  defp value(:uint64), do: :proper_types.integer(0, 0xFFFFFFFFFFFFFFFF)
  defp value(:int64), do: :proper_types.integer(-0x8000000000000000, 0x7FFFFFFFFFFFFFFF)

  defp value(:float) do
    :proper_types.frequency([
      {20, bind(:proper_types.float(-3.0e38, 3.0e38), &float32/1)},
      {20, bind(:proper_types.float(-1000.0, 1000.0), &float32/1)},
      {5, 0.0},
      {1, :proper_types.oneof([:nan, :infinity, :neg_infinity])}
    ])
  end

  defp value(:double),
    do: :proper_types.oneof([:proper_types.float(), :nan, :infinity, :neg_infinity])

  # the float32 nearest to a value
  defp float32(value) do
    <<v::float-32>> = <<value::float-32>>
    v
  end
end
