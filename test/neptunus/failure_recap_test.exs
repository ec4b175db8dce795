defmodule Neptunus.Test.FailureRecapTest do
  use ExUnit.Case, async: true

  alias Neptunus.Test.FailureRecap

  defp failed(name, message) do
    test = %ExUnit.Test{
      name: name,
      module: __MODULE__,
      tags: %{file: Path.expand("test/x_test.exs"), line: 7}
    }

    {test, [{:error, %ExUnit.AssertionError{message: message}, []}]}
  end

  test "names each failed test with its file and line, and the end of its report" do
    report = Enum.map_join(1..50, "\n", &"line #{&1}")
    recap = FailureRecap.recap([failed(:"test one", report)])

    assert recap =~ "Failures again"
    assert recap =~ "1) test one (Neptunus.Test.FailureRecapTest) test/x_test.exs:7"
    assert recap =~ "line 50\n"
    assert recap =~ "line 21\n"
    refute recap =~ "line 20\n"
  end

  test "cuts long lines and lists at most five failures" do
    long = String.duplicate("x", 1_000)
    recap = FailureRecap.recap(for n <- 1..7, do: failed(:"test #{n}", long))

    assert recap =~ "5) test 5"
    refute recap =~ "6) test 6"
    assert recap =~ "… and 2 more"
    refute recap =~ String.duplicate("x", 401)
  end
end
