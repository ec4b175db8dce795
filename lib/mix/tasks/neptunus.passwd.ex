defmodule Mix.Tasks.Neptunus.Passwd do
  @shortdoc "Prints a users-file line with a salted PBKDF2 password hash"
  @moduledoc """
  Hashes a password for the users file (`NEPTUNUS_USERS_FILE`) or `NEPTUNUS_USERS`:

      $ mix neptunus.passwd ada pilot
      Password for ada: ********
      ada pilot pbkdf2-sha256$200000$…$…

      $ printf '%s\\n' "$PASSWORD" | mix neptunus.passwd --iterations 600000 main main_station

  Roles: `pilot`, `observer`, `main_station`. The password is read from standard input (one
  line; typed without echo on a terminal). `--iterations N` sets the PBKDF2 iteration count
  (default 200 000, see `NeptunusWeb.Auth.Password`). `--inline` prints the
  `NEPTUNUS_USERS` form `name:role:hash` instead.

  In a release: `bin/neptunus eval 'IO.puts(NeptunusWeb.Auth.Password.hash("…"))'`.
  """
  use Mix.Task

  alias NeptunusWeb.Auth.Password

  @roles ~w(pilot observer main_station)

  @impl true
  def run(args) do
    {opts, positional, invalid} =
      OptionParser.parse(args, strict: [iterations: :integer, inline: :boolean])

    case {invalid, positional} do
      {[], [name, role]} ->
        unless role in @roles,
          do: Mix.raise("unknown role #{inspect(role)}: use one of #{Enum.join(@roles, ", ")}")

        unless Regex.match?(~r/^[A-Za-z0-9_.@-]{1,40}$/, name),
          do: Mix.raise("bad user name #{inspect(name)}: 1..40 of a-z A-Z 0-9 _ . @ -")

        password = read_password("Password for #{name}: ")
        if password == "", do: Mix.raise("empty password")
        hash = Password.hash(password, Keyword.take(opts, [:iterations]))
        separator = if opts[:inline], do: ":", else: " "
        Mix.shell().info(Enum.join([name, role, hash], separator))

      _ ->
        Mix.raise("usage: mix neptunus.passwd [--iterations N] [--inline] NAME ROLE")
    end
  end

  defp read_password(prompt) do
    line =
      case :io.getopts(:standard_io)[:echo] do
        true ->
          IO.write(:stderr, prompt)
          :io.get_password()

        _ ->
          IO.gets("")
      end

    case line do
      data when is_binary(data) or is_list(data) ->
        data |> to_string() |> String.trim_trailing("\n")

      _ ->
        ""
    end
  end
end
