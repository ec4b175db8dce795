defmodule NeptunusWeb.WireSchema.Docs do
  @moduledoc """
  The tables of docs/API.md that `NeptunusWeb.WireSchema` defines, each between
  `<!-- wire:begin NAME -->` and `<!-- wire:end NAME -->`; the prose around them is written by
  hand. Sections:

    * `vehicle-events`, `fleet-events`, `log-events` — each topic's server events;
    * `commands-GROUP` — the commands of a group (`helm`, `control`, `tuning`, `camera`, `ardusub`,
      `sim`): who may send them, payload, reply, effect, errors;
    * `payloads` — every payload type: its fields, types, units and meaning (anchors
      `#wire-NAME`, which the other tables link to).

  `update/1` regenerates every section of a document and refuses one whose markers do not
  pair up, or that lacks one of the sections.
  """

  alias NeptunusWeb.WireSchema

  @path "docs/API.md"
  @groups [:helm, :control, :tuning, :camera, :ardusub, :sim]

  @doc "The document, relative to the project's root."
  @spec path() :: String.t()
  def path, do: @path

  @doc "The section names, in the order they are expected."
  @spec sections() :: [String.t()]
  def sections do
    ["vehicle-events", "fleet-events", "log-events"] ++
      Enum.map(@groups, &"commands-#{&1}") ++ ["payloads"]
  end

  @doc "`text` with every section regenerated; raises naming a missing or unpaired marker."
  @spec update(String.t()) :: String.t()
  def update(text) do
    Enum.reduce(sections(), text, fn name, acc ->
      open = "<!-- wire:begin #{name} -->\n"
      close = "<!-- wire:end #{name} -->"

      case String.split(acc, open) do
        [before, rest] ->
          case String.split(rest, close) do
            [_old, after_] -> before <> open <> section(name) <> close <> after_
            _ -> raise ArgumentError, "#{@path}: `#{close}` missing or repeated"
          end

        _ ->
          raise ArgumentError, "#{@path}: `#{String.trim(open)}` missing or repeated"
      end
    end)
  end

  @doc "The text of section `name` (without its markers)."
  @spec section(String.t()) :: String.t()
  def section("payloads"), do: IO.iodata_to_binary(Enum.map(WireSchema.definitions(), &payload/1))

  def section("commands-" <> group) do
    group = String.to_existing_atom(group)
    commands = Enum.filter(WireSchema.commands(), &(&1.group == group))

    rows =
      Enum.map(commands, fn c ->
        row([
          code(c.name),
          c.who,
          shape(c.payload),
          shape(c.reply),
          c.doc,
          Map.get(c, :errors, "")
        ])
      end)

    table(["Event", "Who", "Payload", "Reply `ok`", "Effect", "Errors"], rows)
  end

  def section(events) when events in ["vehicle-events", "fleet-events", "log-events"] do
    [topic, _] = String.split(events, "-")

    rows =
      for e <- WireSchema.events(), e.topic == topic do
        when_ = if e[:to], do: "to #{e.to} only: #{e.doc}", else: e.doc
        row([code(e.name), shape(e.payload), when_])
      end

    table(["Event", "Payload", "When"], rows)
  end

  # --- payload types -------------------------------------------------------------------------

  defp payload(%{kind: :object} = object) do
    rows =
      Enum.map(object.fields, fn f ->
        name = if f.optional, do: "#{code(f.name)} (may be absent)", else: code(f.name)
        type = if f.null, do: "#{type(f.type)} \\| null", else: type(f.type)
        row([name, type, f.unit || "", f.doc])
      end)

    body =
      case rows do
        [] -> "No fields: `{}`.\n"
        rows -> table(["Field", "Type", "Unit", "Meaning"], rows)
      end

    [heading(object), sentence(object.doc), "\n\n", body, "\n"]
  end

  defp payload(%{kind: kind} = definition) when kind in [:enum, :union] do
    choices =
      case definition do
        %{values: values} -> Enum.map_join(values, ", ", &literal/1)
        %{types: types} -> Enum.map_join(types, ", ", &type/1)
      end

    [heading(definition), sentence(definition.doc), " One of ", choices, ".\n\n"]
  end

  defp heading(%{name: name}), do: ~s|<a id="wire-#{name}"></a>\n#### `#{name}`\n|

  defp sentence(text), do: String.trim_trailing(text, ".") <> "."

  # --- rendering -----------------------------------------------------------------------------

  # a message's payload: the fields of a small object at a glance (their types linked), else
  # its type
  defp shape(name) when is_atom(name) do
    if WireSchema.primitive?(name) do
      type(name)
    else
      case WireSchema.definition(name) do
        %{kind: :object, fields: []} ->
          "`{}`"

        %{kind: :object, fields: fields} when length(fields) <= 4 ->
          inner =
            Enum.map_join(fields, ", ", fn f ->
              key = if f.optional, do: ~s|"#{f.name}"?|, else: ~s|"#{f.name}"|
              value = if f.null, do: "#{type(f.type)} \\| null", else: type(f.type)
              "#{key}: #{value}"
            end)

          "{#{inner}}"

        _ ->
          type(name)
      end
    end
  end

  defp shape(type), do: type(type)

  defp type(name) when name in [:number, :integer, :string, :boolean], do: Atom.to_string(name)
  defp type({:enum, values}), do: Enum.map_join(values, " \\| ", &literal/1)
  defp type({:list, type}), do: "[#{type(type)}]"
  defp type({:map, type}), do: "{name: #{type(type)}}"
  defp type({:one_of, types}), do: Enum.map_join(types, " \\| ", &type/1)
  defp type({:or_null, type}), do: "#{type(type)} \\| null"
  defp type(name) when is_atom(name), do: "[#{name}](#wire-#{name})"

  defp literal(value) when is_binary(value), do: "`\"#{value}\"`"
  defp literal(value) when is_integer(value), do: "`#{value}`"

  defp code(name), do: "`#{name}`"

  defp table(header, rows) do
    [
      "| ",
      Enum.join(header, " | "),
      " |\n|",
      String.duplicate("---|", length(header)),
      "\n",
      rows
    ]
    |> IO.iodata_to_binary()
  end

  defp row(cells) do
    ["| ", Enum.map_join(cells, " | ", &cell/1), " |\n"]
  end

  # a table cell: one line, its own pipes escaped (those of types are escaped already)
  defp cell(text) do
    text
    |> String.replace(~r/\s*\n\s*/, " ")
    |> String.replace(~r/(?<!\\)\|/, "\\|")
  end
end
