defmodule Neptunus.Test.Properties do
  @moduledoc """
  PropEr from ExUnit: `check(generator, fn value -> boolean end, numtests)` runs the property
  and fails the test with the (shrunk) counterexample.

  An exception inside the property counts as a failure with its counterexample, so "never
  crashes" is just `fn x -> f(x); true end`. (Debian's PropEr 1.2 calls
  `erlang:get_stacktrace/0`, gone since OTP 23, when a property raises; we catch the exception
  ourselves and report it.)

  Generators are `:proper_types` values; `bind/2` is PropEr's `?LET`.
  """
  import ExUnit.Assertions

  @spec check(term(), (term() -> boolean()), pos_integer()) :: :ok
  def check(generator, property, numtests \\ 500) do
    Process.delete(:property_exception)
    prop = :proper.forall(generator, &safely(property, &1))

    case :proper.quickcheck(prop, [:quiet, {:numtests, numtests}]) do
      true ->
        :ok

      other ->
        flunk("""
        property failed (#{inspect(other)})
        counterexample: #{inspect(:proper.counterexample(), limit: :infinity, binaries: :as_strings)}
        #{exception_text()}
        """)
    end
  end

  @doc "A JSON scalar: null, a boolean, an integer, a float or a UTF-8 string."
  @spec json_leaf() :: term()
  def json_leaf do
    :proper_types.oneof([
      :proper_types.exactly(nil),
      :proper_types.boolean(),
      :proper_types.integer(),
      :proper_types.float(),
      :proper_unicode.utf8()
    ])
  end

  @doc "PropEr's `?LET(X, Gen, f(X))`."
  @spec bind(term(), (term() -> term())) :: term()
  def bind(generator, fun), do: :proper_types.bind(generator, fun, false)

  defp safely(property, value) do
    property.(value) == true
  rescue
    exception ->
      Process.put(:property_exception, Exception.format(:error, exception, __STACKTRACE__))
      false
  end

  defp exception_text do
    case Process.get(:property_exception) do
      nil -> ""
      text -> "last exception raised by the property:\n" <> text
    end
  end
end
