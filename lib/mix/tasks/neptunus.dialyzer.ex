defmodule Mix.Tasks.Neptunus.Dialyzer do
  @shortdoc "Type-checks the application with dialyzer (Debian's erlang-dialyzer)"
  @moduledoc """
  Runs dialyzer's success typing over the compiled application: wrong `@spec`s, calls that
  can never succeed, dead clauses. Exits non-zero on any warning.

      mix neptunus.dialyzer

  The PLT (the analysed OTP, Elixir, yaws and jiffy modules) is built once per machine into
  the build directory (`_build/dev/neptunus-<OTP release>.plt`; a few minutes on two cores)
  and reused. `make test`
  runs this task after the tests.
  """
  use Mix.Task

  @otp_apps [:erts, :kernel, :stdlib, :crypto, :ssl, :public_key, :inets, :compiler]
  @elixir_apps [:elixir, :logger, :eex, :mix]

  @impl true
  def run(_args) do
    Mix.Task.run("compile")

    plt = Path.join(Mix.Project.build_path(), "neptunus-#{System.otp_release()}.plt")

    unless File.exists?(plt) do
      Mix.shell().info("Building the dialyzer PLT #{plt} (once per machine)…")
      started_ms = Neptunus.Clock.monotonic_ms()

      _ =
        :dialyzer.run(
          analysis_type: :plt_build,
          output_plt: String.to_charlist(plt),
          files_rec: plt_dirs()
        )

      Mix.shell().info("PLT built in #{div(Neptunus.Clock.monotonic_ms() - started_ms, 1000)} s")
    end

    ebin = Path.join(Mix.Project.app_path(), "ebin")
    Mix.shell().info("dialyzer: #{ebin}")

    warnings =
      :dialyzer.run(
        analysis_type: :succ_typings,
        init_plt: String.to_charlist(plt),
        files_rec: [String.to_charlist(ebin)],
        warnings: [:no_improper_lists]
      )

    Enum.each(warnings, &Mix.shell().error(to_string(:dialyzer.format_warning(&1))))

    case warnings do
      [] -> Mix.shell().info("dialyzer: no warnings")
      _ -> Mix.raise("dialyzer: #{length(warnings)} warning(s)")
    end
  end

  defp plt_dirs do
    erlang = for app <- @otp_apps, do: :code.lib_dir(app, :ebin)
    elixir = for app <- @elixir_apps, do: :code.lib_dir(app, :ebin)
    deps = for app <- [:yaws, :jiffy], dir = :code.lib_dir(app, :ebin), is_list(dir), do: dir
    erlang ++ elixir ++ deps
  end
end
