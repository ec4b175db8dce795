defmodule Mix.Tasks.Compile.PortPrograms do
  @shortdoc "Builds the C port programs and NIF libraries in c_src/ into priv/"
  @moduledoc """
  Builds every `c_src/NAME.c` into `priv/NAME` with the system C compiler (`$CC`, else `cc`,
  else `gcc`; `make setup` installs gcc) and `-Wall -Wextra -Werror -O2`; a `c_src/NAME_nif.c`
  becomes the shared library `priv/NAME_nif.so` (with Erlang's `erl_nif.h` from `erlang-dev`,
  and `-ffp-contract=off` so its floating point matches the BEAM's); everything is linked with
  the maths library (`-lm`). A program is rebuilt
  when it is missing or any file in `c_src/` is at least as new as it (mtimes have 1 s
  resolution, so "as new" rebuilds rather than misses a change made in the same second).
  The binary is written to a temporary name and renamed into place, so builds from several
  `_build` directories at once never leave a half-written program. Binaries are git-ignored.

  Cross-compiling (`rel/armhf/build`, for the armhf board): `CC=arm-linux-gnueabihf-gcc mix
  compile.port_programs --force --out DIR --erl-include INCLUDE` builds the same programs with
  the same flags into `DIR` instead of `priv/`, against the target Erlang's `erl_nif.h`
  (`INCLUDE`: the sizes of C types in it differ between 32- and 64-bit machines).
  """
  use Mix.Task.Compiler

  @cflags ~w(-std=c99 -Wall -Wextra -Werror -O2)

  @impl true
  def run(args) do
    # `mix compile` passes its own options (--warnings-as-errors, ...) to every compiler
    {opts, _, _} =
      OptionParser.parse(args, switches: [out: :string, erl_include: :string, force: :boolean])

    out = Keyword.get(opts, :out, "priv")
    include = Keyword.get(opts, :erl_include, Path.join([:code.root_dir(), "usr", "include"]))
    File.mkdir_p!(out)
    sources = Path.wildcard("c_src/*.c")
    newest = "c_src/*" |> Path.wildcard() |> Enum.map(&mtime/1) |> Enum.max(fn -> 0 end)

    results =
      for source <- sources,
          target = target(source, out),
          opts[:force] || stale?(target, newest),
          do: build(source, target, include)

    cond do
      results == [] -> {:noop, []}
      Enum.all?(results, &(&1 == :ok)) -> {:ok, []}
      # run by itself (cross-compiling) nothing else would turn errors into an exit status
      opts[:out] -> Mix.raise("compile.port_programs: could not build every program")
      true -> {:error, for({:error, diagnostic} <- results, do: diagnostic)}
    end
  end

  @impl true
  def clean, do: Enum.each(Path.wildcard("c_src/*.c"), &File.rm(target(&1, "priv")))

  defp target(source, out) do
    name = Path.basename(source, ".c")
    if nif?(source), do: Path.join(out, name <> ".so"), else: Path.join(out, name)
  end

  defp nif?(source), do: String.ends_with?(source, "_nif.c")

  defp flags(source, include) do
    if nif?(source) do
      @cflags ++ ~w(-ffp-contract=off -fPIC -shared -I) ++ [include]
    else
      @cflags
    end
  end

  defp libs(_source), do: ["-lm"]

  defp stale?(target, newest), do: not File.exists?(target) or mtime(target) <= newest

  defp mtime(path) do
    case File.stat(path, time: :posix) do
      {:ok, %File.Stat{mtime: mtime}} -> mtime
      {:error, _} -> 0
    end
  end

  defp build(source, target, include) do
    cc = System.get_env("CC") || System.find_executable("cc") || System.find_executable("gcc")
    tmp = "#{target}.#{System.unique_integer([:positive])}.tmp"

    with cc when is_binary(cc) <- cc,
         {_output, 0} <-
           System.cmd(cc, flags(source, include) ++ ["-o", tmp, source] ++ libs(source),
             stderr_to_stdout: true
           ) do
      File.rename!(tmp, target)
      Mix.shell().info("Compiled #{source} -> #{target}")
      :ok
    else
      nil ->
        failure(source, "no C compiler found: install gcc (`make setup`)")

      {output, _status} ->
        _ = File.rm(tmp)
        failure(source, output)
    end
  end

  defp failure(source, message) do
    Mix.shell().error("could not build #{source}:\n#{message}")

    {:error,
     %Mix.Task.Compiler.Diagnostic{
       compiler_name: "port_programs",
       file: Path.absname(source),
       message: message,
       position: nil,
       severity: :error
     }}
  end
end

defmodule Neptunus.MixProject do
  use Mix.Project

  @version "0.1.0"

  # yaws is installed by Debian outside the Erlang lib dir (/usr/lib/yaws-2.1.1).
  # `make setup` links it into erl_libs/ (git-ignored); we put its ebin on the code
  # path and start its processes under our own supervisor (NeptunusWeb.Endpoint): started as an
  # application without a configuration, yaws would stop the VM.
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
      # c_src/neptunus_uart.c → priv/neptunus_uart (the serial port program),
      # c_src/neptunus_camera.c → priv/neptunus_camera (the camera port program and the
      # simulated camera's renderer), the NIFs neptunus_dynamics_nif and neptunus_os_nif →
      # priv/*.so, see above
      compilers: Mix.compilers() ++ [:port_programs],
      deps: [],
      # dev tooling that is not part of the running application (mix neptunus.dialyzer)
      xref: [exclude: [:dialyzer]],
      aliases: aliases(),
      releases: releases()
    ]
  end

  def application do
    [
      mod: {Neptunus.Application, []},
      extra_applications: [:logger, :crypto, :ssl, :jiffy] ++ extra_apps(Mix.env()),
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

  # `NEPTUNUS_ERTS` (set by rel/armhf/build): the erts directory of another machine's Erlang
  # to put in the release instead of this machine's (the board's armhf erts).
  # `NEPTUNUS_RELEASE_VERSION`: a release version other than the application's (a rebuild of
  # the same version to install beside it: releases are installed by release version).
  defp releases do
    [
      neptunus: [
        version: System.get_env("NEPTUNUS_RELEASE_VERSION") || @version,
        include_executables_for: [:unix],
        include_erts: System.get_env("NEPTUNUS_ERTS") || true,
        steps: [:assemble, &install_files/1]
      ]
    ]
  end

  # What installs and runs the release on a machine, carried in it: bin/neptunus-install,
  # etc/neptunus.service (the systemd unit) and etc/neptunus.env (the settings' template).
  # Also yaws' include files: yaws compiles a module at startup that includes them (mix copies
  # only ebin/ and priv/ of an application), and logs errors without them.
  defp install_files(release) do
    with yaws when is_list(yaws) <- release.applications[:yaws],
         source = Path.join(to_string(yaws[:path]), "include"),
         true <- File.dir?(source) do
      File.cp_r!(source, Path.join([release.path, "lib", "yaws-#{yaws[:vsn]}", "include"]))
    end

    bin = Path.join(release.path, "bin/neptunus-install")
    File.cp!("rel/neptunus-install", bin)
    File.chmod!(bin, 0o755)
    etc = Path.join(release.path, "etc")
    File.mkdir_p!(etc)
    File.cp!("rel/neptunus.service", Path.join(etc, "neptunus.service"))
    File.cp!("rel/neptunus.env", Path.join(etc, "neptunus.env"))
    release
  end
end
