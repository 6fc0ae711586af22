"""The commands of `stewart-sim`, one module each (FMPy's command_line.py as the model): a
module's `add_parser(sub, help)` declares its arguments and `run(args)` does its work over one
library call or a few. stewart_sim.cli.COMMANDS lists them.

A command module imports only the standard library at its top (`--help` answers at once); the
packages its work needs are imported inside `run`. Defaults that live in heavier modules are
read from their source text by stewart_sim.commands.constants.literals, not copied.
"""
