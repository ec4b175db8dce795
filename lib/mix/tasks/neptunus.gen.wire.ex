defmodule Mix.Tasks.Neptunus.Gen.Wire do
  @shortdoc "Writes the wire schema's TypeScript and the docs' payload tables"
  @moduledoc """
  Derives the copies of the wire schema (`NeptunusWeb.WireSchema`):

    * `assets/src/lib/wire.gen.ts` — the payloads' TypeScript types and decoders;
    * docs/API.md — the tables between `<!-- wire:begin NAME -->` and `<!-- wire:end NAME -->`.

  Run it after changing the schema and commit what it wrote (the browser build needs no
  Elixir); `mix test` fails while a copy is out of date. `--check` writes nothing and exits
  non-zero, naming the files, when one is.

      $ mix neptunus.gen.wire
      $ mix neptunus.gen.wire --check
  """
  use Mix.Task

  alias NeptunusWeb.WireSchema

  @impl true
  def run(args) do
    {opts, _rest} = OptionParser.parse!(args, strict: [check: :boolean])
    check? = Keyword.get(opts, :check, false)
    Mix.Task.run("compile")
    root = File.cwd!()

    stale =
      for {path, text} <- WireSchema.Derived.files(root),
          File.read(Path.join(root, path)) != {:ok, text} do
        unless check?, do: File.write!(Path.join(root, path), text)
        path
      end

    cond do
      check? and stale != [] ->
        Mix.raise("out of date (run mix neptunus.gen.wire): #{Enum.join(stale, ", ")}")

      check? ->
        Mix.shell().info("the wire schema's copies are up to date")

      stale == [] ->
        Mix.shell().info("nothing to write: the wire schema's copies are up to date")

      true ->
        Enum.each(stale, &Mix.shell().info("wrote #{&1}"))
    end
  end
end
