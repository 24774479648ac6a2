"""Flight tests of the platforms: scenarios (hover, step, square, payload, reference), their metrics and plots.

`runner.fly(FlightRequest(...))` is what `aerobench fly` and `make demo` run.
"""
