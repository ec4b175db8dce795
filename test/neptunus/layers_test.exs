defmodule Neptunus.LayersTest do
  # The core (Neptunus.*) does not call the web layer (NeptunusWeb.*): JSON is
  # Neptunus.JSON, and the wire format of PubSub's fastlane frames is given to the PubSub
  # by the application. Only the application, which starts both, and the configuration
  # (user password hashes are checked with NeptunusWeb.Auth.Password) may.
  use ExUnit.Case, async: true

  @edge [Neptunus.Application, Neptunus.Config.Auth]

  test "no core module calls a NeptunusWeb function" do
    {:ok, modules} = :application.get_key(:neptunus, :modules)

    calls =
      for module <- modules,
          core?(module),
          module not in @edge,
          {:ok, {^module, [imports: imports]}} =
            :beam_lib.chunks(:code.which(module), [:imports]),
          {callee, fun, arity} <- imports,
          web?(callee),
          do: "#{inspect(module)} calls #{inspect(callee)}.#{fun}/#{arity}"

    assert calls == []
  end

  # the test support modules (Neptunus.Test.*, compiled into the test build) are not the core
  defp core?(module) do
    name = Atom.to_string(module)

    String.starts_with?(name, "Elixir.Neptunus.") and
      not String.starts_with?(name, "Elixir.Neptunus.Test.")
  end

  defp web?(module), do: String.starts_with?(Atom.to_string(module), "Elixir.NeptunusWeb.")
end
