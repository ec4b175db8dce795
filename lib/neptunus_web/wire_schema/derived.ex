defmodule NeptunusWeb.WireSchema.Derived do
  @moduledoc """
  The files derived from `NeptunusWeb.WireSchema`, as they must read: the TypeScript
  (`NeptunusWeb.WireSchema.TypeScript`) and docs/API.md with its tables regenerated
  (`NeptunusWeb.WireSchema.Docs`). `mix neptunus.gen.wire` writes them; the wire schema test
  compares them with the committed files.
  """

  alias NeptunusWeb.WireSchema.{Docs, TypeScript}

  @doc "`[{path, text}]`, paths relative to `root` (the project's root)."
  @spec files(Path.t()) :: [{String.t(), String.t()}]
  def files(root) do
    [
      {TypeScript.path(), TypeScript.generate()},
      {Docs.path(), Docs.update(File.read!(Path.join(root, Docs.path())))}
    ]
  end
end
