defmodule Neptunus.MixProject do
  use Mix.Project

  @version "0.1.0"

  # yaws is installed by Debian outside the Erlang lib dir (/usr/lib/yaws-2.1.1).
  # `make setup` links it into erl_libs/ (git-ignored); we put its ebin on the code
  # path and start its processes under our own supervisor (see STACK_NOTES.md).
  @yaws_dir Path.wildcard(Path.join(__DIR__, "erl_libs/yaws-*")) |> List.first()

  if @yaws_dir do
    Code.prepend_path(Path.join(@yaws_dir, "ebin"))
  else
    Mix.shell().error(
      "yaws not found in erl_libs/: run `make setup` (it links Debian's erlang-yaws there)"
    )
  end

  def project do
    [
      app: :neptunus,
      version: @version,
      elixir: "~> 1.14",
      start_permanent: Mix.env() == :prod,
      elixirc_paths: elixirc_paths(Mix.env()),
      deps: [],
      aliases: aliases(),
      releases: releases()
    ]
  end

  def application do
    [
      mod: {Neptunus.Application, []},
      extra_applications: [:logger, :crypto, :jiffy] ++ extra_apps(Mix.env()),
      included_applications: [:yaws]
    ]
  end

  defp extra_apps(:test), do: [:proper]
  defp extra_apps(_), do: []

  defp elixirc_paths(:test), do: ["lib", "test/support"]
  defp elixirc_paths(_), do: ["lib"]

  defp aliases do
    []
  end

  defp releases do
    [neptunus: [include_executables_for: [:unix]]]
  end
end
