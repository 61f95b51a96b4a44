"""``renderlab check-method KIND METHOD``: run a method through its observable kind's conformance harness.

``KIND`` is a registered observable kind (:data:`renderlab.plugins.observables`: the lab's ``landmark``, ``filter``,
``pose``, ``centre_limb``, and any a package registers under the entry-point group ``renderlab.observables``);
``METHOD`` a method registered for it (:func:`renderlab.plugins.method_registry`) or a ``module:attr`` typed here.
The harness is the kind's ``conformance(factory) -> list[str]`` (:mod:`renderlab.contracts.observable`). Each broken
rule is printed on its own line; the exit code is 0 when the method conforms, 1 when it does not, 2 for bad input.
"""

from __future__ import annotations

from renderlab.errors import UserError
from renderlab.inputs import short


def add_parser(subparsers) -> None:
    p = subparsers.add_parser("check-method", help="run a method through its observable kind's conformance harness "
                                                   "(exit 0: conforms, 1: a rule is broken)")
    p.add_argument("kind", metavar="KIND", help="observable kind (landmark, filter, centre_limb, or a plug-in's)")
    p.add_argument("method", metavar="METHOD", help="method registered for the kind, or module:attr")


def run(args) -> int:
    from renderlab import plugins
    from renderlab.commands.references import load_reference

    kind = plugins.observable(args.kind)
    harness = kind.part("conformance")
    if harness is None:
        raise UserError(f"observable kind '{kind.name}' has no conformance harness")
    registry = plugins.method_registry(kind)
    if ":" in args.method:
        factory = load_reference(args.method, "METHOD")
        if plugins.kind_of_method(factory) is not kind:
            raise UserError(f"METHOD: {short(args.method)} is not a {kind.name} method (a class with "
                            f"{', '.join(sorted(plugins.protocol_methods(kind.protocol)))})")
    else:
        factory = registry.get(args.method)
    failures = list(harness(factory))
    for line in failures:
        print(line)
    verdict = "conforms" if not failures else f"breaks {len(failures)} rule(s)"
    print(f"renderlab: {kind.name} method {args.method} {verdict} ({kind.conformance})")
    return 0 if not failures else 1
