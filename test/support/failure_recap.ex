defmodule Neptunus.Test.FailureRecap do
  @max_failures 5
  @max_lines 30
  @max_line_chars 400

  @moduledoc """
  An ExUnit formatter that repeats, at the very end of the run, which tests failed and the
  last lines of each failure's report.

  ExUnit prints a failure when its test ends, which in a run of a thousand tests is far from
  the end; a CI log that keeps only its tail would show "1 failure" and not which assertion.
  This recap comes after ExUnit's summary (it prints when the formatters stop, after
  ExUnit's own formatter has printed): for each failure (at most #{@max_failures}) the test,
  its file and line, and the last #{@max_lines} lines of its report (each cut at
  #{@max_line_chars} characters) — for a Node suite run by
  `test/e2e/external_test.exs`, the failing subtests and their errors.
  """
  use GenServer

  @impl true
  def init(_opts), do: {:ok, %{failures: []}}

  @impl true
  def handle_cast({:test_finished, %ExUnit.Test{state: {:failed, failures}} = test}, state),
    do: {:noreply, %{state | failures: [{test, failures} | state.failures]}}

  def handle_cast({:module_finished, %ExUnit.TestModule{state: {:failed, failures}} = m}, state),
    do: {:noreply, %{state | failures: [{m, failures} | state.failures]}}

  def handle_cast(_event, state), do: {:noreply, state}

  @impl true
  def terminate(_reason, %{failures: []}), do: :ok

  def terminate(_reason, %{failures: failures}) do
    failures = Enum.reverse(failures)
    IO.puts(["\n", recap(failures)])
  end

  @doc "The recap of `[{test or module, failures}]`, as printed."
  @spec recap([{ExUnit.Test.t() | ExUnit.TestModule.t(), term()}]) :: String.t()
  def recap(failures) do
    shown = Enum.take(failures, @max_failures)
    more = length(failures) - length(shown)

    body =
      shown
      |> Enum.with_index(1)
      |> Enum.map(fn {{what, reports}, n} ->
        ["#{n}) ", title(what), "\n", indent(tail(reports))]
      end)

    IO.iodata_to_binary([
      "Failures again (the full reports are above):\n",
      Enum.intersperse(body, "\n"),
      if(more > 0, do: "\n… and #{more} more\n", else: "")
    ])
  end

  defp title(%ExUnit.Test{name: name, module: module, tags: tags}),
    do: "#{name} (#{inspect(module)}) #{Path.relative_to_cwd(tags[:file] || "")}:#{tags[:line]}"

  defp title(%ExUnit.TestModule{name: module, file: file}),
    do: "#{inspect(module)} (setup_all) #{Path.relative_to_cwd(file || "")}"

  defp tail(reports) do
    reports
    |> Enum.map_join("\n", &text/1)
    |> String.split("\n")
    |> Enum.reject(&(String.trim(&1) == ""))
    |> Enum.take(-@max_lines)
    |> Enum.map(&String.slice(&1, 0, @max_line_chars))
  end

  # an assertion's own message (a Node suite's output), else the exception's banner
  defp text({_kind, %ExUnit.AssertionError{message: message}, _stack}), do: message
  defp text({kind, reason, stack}), do: Exception.format_banner(kind, reason, stack)

  defp indent(lines), do: Enum.map(lines, &["     ", &1, "\n"])
end
