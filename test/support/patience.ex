defmodule Neptunus.Test.Patience do
  @moduledoc """
  How long a test waits for something that must happen before it calls the wait a failure.

  A wait in a test is for an event (a message, a frame, a line on a pty, a state reached),
  never a measurement: it returns as soon as the event comes, and its bound only keeps a
  broken test from hanging. The machine the suite runs on may be shared and busy (`make test`
  holds with both cores kept busy by another program), so the bound is generous: one figure,
  used as ExUnit's `assert_receive` default (test/test_helper.exs) and by the waits in
  test/support. Performance is measured in bench/, never bounded here.
  """

  @ms 15_000

  @doc "The bound of a wait for an event that must come (ms)."
  @spec ms() :: pos_integer()
  def ms, do: @ms
end
