"""Any registered observable kind's methods over frames → the kind's checked result table.

:func:`measure_frames` is the generic path a study takes for a kind registered in
:data:`renderlab.plugins.observables` (:mod:`renderlab.contracts.observable`): the kind's method (registered name or
object), its ``runner(method, frames) -> list[dict]`` (one row per result), then the table typed with the kind's
known schema, every ``reason`` checked against the kind's enum and the core columns checked. Nothing here names a
kind: a kind a package registers runs exactly like the lab's own.
"""

from __future__ import annotations

from renderlab import plugins
from renderlab.contracts.schemas import check_table, table_from_rows
from renderlab.errors import UserError


def make_kind_method(kind, method, *args, **kwargs):
    """A method of ``kind`` from its registered name (``factory(*args, **kwargs)``), or ``method`` itself when it is
    already an object that follows the kind's protocol."""
    kind = plugins.observable(kind) if isinstance(kind, str) else kind
    if isinstance(method, str):
        return plugins.method_registry(kind).get(method, where=f"{kind.name}: ")(*args, **kwargs)
    if plugins.kind_of_method(method) is not kind:
        raise UserError(f"{type(method).__name__} is not a {kind.name} method "
                        f"(needs {', '.join(sorted(plugins.protocol_methods(kind.protocol)))})")
    return method


def measure_frames(kind, method, frames, *, campaign: str = "", run: int = 0):
    """``method`` (name or object) of the registered ``kind`` (name or object) over ``frames`` by the kind's
    ``runner``: a ``pyarrow.Table`` of the kind (``campaign`` and ``run`` filled where the rows lack them; columns the
    rows add beyond the kind's known schema appended). ``ValueError`` names a broken reason or a missing column."""
    kind = plugins.observable(kind) if isinstance(kind, str) else kind
    runner, schema = kind.part("runner"), kind.known_columns()
    if runner is None or schema is None:
        raise UserError(f"observable kind '{kind.name}' has no generic runner or result schema")
    import pyarrow as pa

    rows = [{"campaign": campaign, "run": run, **row} for row in runner(make_kind_method(kind, method), frames)]
    given = set().union(*(r.keys() for r in rows)) if rows else set()
    core = set(kind.core_schema().names)
    schema = pa.schema([f for f in schema if f.name in core or f.name in given])  # optional columns only when given
    table = table_from_rows(rows, schema, kind.name) if rows else schema.empty_table()
    check_table(table, kind.name, where=f"{kind.name} runner")
    return table
