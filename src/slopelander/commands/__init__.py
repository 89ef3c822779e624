"""The ``slopelander`` commands, one module each: its options and a thin ``run(args)`` that calls
the library (the work itself lives in the parts: controller, legs, model, envelope, ident).

A command must answer at once: these modules import only the standard library, yaml and the leg
protocol at module level; the model, numba, scipy, matplotlib and tqdm are imported inside ``run``
(tests/cli/test_cli_latency.py checks it). The option names follow one scheme, and renamed ones
keep their old spelling working (:mod:`slopelander.commands.options`, docs/commands.md).
"""

from __future__ import annotations

#: module -> (the subcommands it adds, whether they need the ``sim`` extra), in ``--help`` order;
#: on a companion computer with the core alone, the simulation's are listed but say which extra
#: they need. Another installed part adds its commands through an entry-point group
#: (:data:`slopelander.cli.COMMANDS_GROUP`): the simulator's ``demo``.
COMMANDS: dict[str, tuple[tuple[str, ...], bool]] = {
    "slopelander.commands.land": (("land",), False),
    "slopelander.commands.legs": (("legs",), False),
    "slopelander.commands.simulate": (("simulate",), True),
    "slopelander.commands.params": (("params",), True),
    "slopelander.commands.map": (("map",), True),
    "slopelander.commands.table": (("table",), True),
    "slopelander.commands.lookup": (("lookup",), False),
    "slopelander.commands.import_": (("import",), True),
    "slopelander.commands.synth": (("synth",), True),
    "slopelander.commands.compare": (("compare",), True),
    "slopelander.commands.fit": (("fit",), True),
    "slopelander.commands.diagnose": (("diagnose",), True),
    "slopelander.commands.steps": (("steps",), True),
}
