"""``magsoro reproduce [NAME ...] [--list] [--preview]``: reproduce robots of the library (docs/robots.md)."""


def register(sub):
    from magsoro.robots.cli import add_arguments, run_reproduce

    p = sub.add_parser(
        "reproduce",
        help="run a robot of the library and draw the quantity its paper plots",
        description="Run robots from the source documents (scenes/NAME.toml) and write the reported quantity as "
                    "CSV and PNG (with the paper's values), an animation, and the acceptance checks. "
                    "Exit 1 when a check fails. See docs/robots.md.",
    )
    add_arguments(p)
    p.set_defaults(func=run_reproduce)
