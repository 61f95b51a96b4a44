"""Table schemas, written once: the measurement (landmark), filter and pose tables of the lab.

Which schema a kind of table has is said by its registered observable kind (:data:`renderlab.plugins.observables`,
``result_schema`` / ``known_schema``); :func:`table_kind`, :func:`expected_kind` and the checks below read that
registry, so a kind registered by a plug-in is detected and checked like the lab's own.

Every runner builds its table with these schemas, every scorer and report reads columns by these names,
and the tests import them. Studies may append their own columns after the schema's (e.g. ``range_m``,
``crlb_s``); :func:`check_table` verifies the schema's columns and types are there.

Landmark measurement table (one row per landmark attempted per image; px unless stated):

========================  =======  =============================================================
column                    type     meaning
========================  =======  =============================================================
campaign, run             str,int  campaign name and run index
frame, item               int      frame index; landmark id
method                    str      registered landmark-method name
pred_s, pred_l            float    landmark centre projected with the a-priori pose and believed camera
meas_s, meas_l            float    pred + measured shift (NaN without result)
truth_s, truth_l          float    true projection (``landmark_truth.parquet`` when present)
err_s, err_l              float    meas − truth
score                     float    the method's match score (correlation coefficient for NCC methods)
has_result                bool     a shift was measured
reason                    dict     :class:`~renderlab.contracts.reasons.LandmarkReason` value
outlier                   bool     flagged by the method's own consistency check, kept
diagnostics               str      the method's own flags as text (not for scoring)
t_ms                      float    wall time of the measurement (excluded from bit-identity checks)
========================  =======  =============================================================

The landmark runner adds: ``peak`` (finder), ``search_px``, ``n_pixels``, ``pred_shadow_fraction``,
``truth_visible``, the a-priori draw ``apriori_dpos_{x,y,z}_m`` / ``apriori_drot_{x,y,z}_rad`` with its 1σ
``apriori_sigma_pos_{x,y,z}_m`` / ``apriori_sigma_att_{x,y,z}_rad`` and ``n_sigma``, the truth geometry
``gsd_ratio``, ``phase_deg``, ``incidence_deg``, ``emission_deg``, ``shadow_fraction``, and ``photometry``.

Filter table (one row per run and time): ``run, t_s, has_result`` (a measurement update happened) and ``reason``
(:class:`~renderlab.contracts.reasons.FilterReason`), then errors ``err_*`` and, for filters with a covariance, their
1σ ``sig_*`` (units in the name: ``_m``, ``_mps``), ``nees`` (state dof), ``nis`` (2 per line of sight; NaN without
measurement) and ``n_meas``.

Pose score table (one row per run): ``campaign, run, has_result, reason``
(:class:`~renderlab.contracts.reasons.PoseReason`), ``diagnostics`` and the study's scores.
"""

from __future__ import annotations

import pyarrow as pa

from renderlab.contracts.reasons import reason_values
from renderlab.errors import UserError
from renderlab.inputs import LIMITS, open_regular

F64, I64, STR, BOOL = pa.float64(), pa.int64(), pa.string(), pa.bool_()
REASON = pa.dictionary(pa.int32(), pa.string())

LANDMARK_CORE = pa.schema([
    ("campaign", STR), ("run", I64), ("frame", I64), ("item", I64), ("method", STR),
    ("pred_s", F64), ("pred_l", F64), ("meas_s", F64), ("meas_l", F64), ("truth_s", F64), ("truth_l", F64),
    ("err_s", F64), ("err_l", F64), ("score", F64), ("has_result", BOOL), ("reason", REASON), ("outlier", BOOL),
    ("diagnostics", STR), ("t_ms", F64),
])

LANDMARK_RUNNER = pa.schema(list(LANDMARK_CORE) + [
    ("peak", STR), ("search_px", I64), ("n_pixels", I64), ("pred_shadow_fraction", F64), ("truth_visible", BOOL),
    *[(f"apriori_dpos_{a}_m", F64) for a in "xyz"], *[(f"apriori_drot_{a}_rad", F64) for a in "xyz"],
    *[(f"apriori_sigma_pos_{a}_m", F64) for a in "xyz"], *[(f"apriori_sigma_att_{a}_rad", F64) for a in "xyz"],
    ("n_sigma", F64), ("gsd_ratio", F64), ("phase_deg", F64), ("incidence_deg", F64), ("emission_deg", F64),
    ("shadow_fraction", F64), ("photometry", STR),
])

FILTER_CORE = pa.schema([("run", I64), ("t_s", F64), ("has_result", BOOL), ("reason", REASON)])

POSE_CORE = pa.schema([("campaign", STR), ("run", I64), ("has_result", BOOL), ("reason", REASON),
                       ("diagnostics", STR)])

#: ``centre_truth.parquet`` of the planet world: one row per body and frame (true pose and camera). ``centre_*`` is the
#: projected body centre (camera model, distortion included); ``limb_*`` the true limb conic (the tangent cone of the
#: ellipsoid through the distortion-free pinhole ``K``, :mod:`renderlab.geometry.conic`): centre, semi-axes a ≥ b,
#: major-axis angle from +s toward +l; ``apparent_radius_px`` = √(ab); ``range_m`` camera to centre; ``los_cam_*`` the
#: unit line of sight, camera frame; ``phase_deg`` Sun–centre–camera; ``cone_*`` the limb cone M (eq. 1 of
#: :mod:`renderlab.geometry.conic`, unit Frobenius norm, xᵀMx > 0 on rays that hit the body) in the camera frame;
#: ``limb_in_image`` the whole conic inside the image; ``limb_model`` ``ellipsoid`` (the rendered body) or
#: ``equivalent_ellipsoid`` (a mesh body: the ellipsoid of its volume and second moments).
CENTRE_TRUTH = pa.schema([
    ("frame", I64), ("time_s", F64), ("body", STR), ("centre_s", F64), ("centre_l", F64),
    ("limb_centre_s", F64), ("limb_centre_l", F64), ("limb_a_px", F64), ("limb_b_px", F64), ("limb_angle_rad", F64),
    ("apparent_radius_px", F64), ("range_m", F64), ("los_cam_x", F64), ("los_cam_y", F64), ("los_cam_z", F64),
    ("phase_deg", F64), *[(f"cone_{k}", F64) for k in ("xx", "xy", "xz", "yy", "yz", "zz")],
    ("limb_in_image", BOOL), ("limb_model", STR),
])


#: a truth set's landmark catalogue (``landmarks.parquet``, :mod:`renderlab.worlds.ev5.catalog`)
LANDMARK_CATALOG = pa.schema([
    ("landmark_id", I64), ("center_x_m", F64), ("center_y_m", F64), ("center_z_m", F64), ("spacing_m", F64),
    ("size_px", I64), ("q_body_from_maplet_x", F64), ("q_body_from_maplet_y", F64), ("q_body_from_maplet_z", F64),
    ("q_body_from_maplet_w", F64), ("maplet_file", STR),
])
#: the columns of a truth set's per-frame landmark truth (``landmark_truth.parquet``) its readers use
LANDMARK_TRUTH = pa.schema([("frame", I64), ("landmark_id", I64), ("s", F64), ("l", F64)])
#: truth-set table name → the schema its readers rely on (:meth:`renderlab.files.truthset.TruthSet.read_table`)
TRUTH_TABLES = {"landmark_truth": LANDMARK_TRUTH}

#: columns holding wall-clock timings (excluded from bit-identity checks)
TIMING_COLUMNS = ("t_ms",)


def _core_schemas() -> dict[str, pa.Schema]:
    """Registered kind → the columns every table of it has (kinds without a result schema left out)."""
    from renderlab import plugins

    return {k.name: s for k in plugins.observable_kinds() if (s := k.core_schema()) is not None}


def core_schema(kind: str) -> pa.Schema:
    """The columns every table of a registered kind has."""
    from renderlab import plugins

    schema = plugins.observable(kind).core_schema()
    if schema is None:
        raise ValueError(f"observable kind {kind!r} has no result schema")
    return schema


def known_schema(kind: str) -> pa.Schema:
    """Every column the readers of a registered kind know (core and optional), with its type."""
    from renderlab import plugins

    return plugins.observable(kind).known_columns()


#: columns the campaign engine adds to every table: they tell no kind apart
IDENTITY_COLUMNS = ("campaign", "run")


def table_kind(table: pa.Table) -> str:
    """The registered observable kind of a table from its columns, or ``"other"``: of the kinds whose every core
    column is there, the one with the most core columns beside ``campaign``/``run`` (``landmark`` over ``pose``); on a
    tie the one registered first (:func:`renderlab.plugins.observable_kinds`: ``filter`` over ``pose``)."""
    names = set(table.column_names)
    fits = [(len(set(s.names) - set(IDENTITY_COLUMNS)), kind) for kind, s in _core_schemas().items()
            if set(s.names) <= names]
    return max(fits, key=lambda f: f[0])[1] if fits else "other"  # max keeps the first of equals


def reason_array(values, kind: str) -> pa.DictionaryArray:
    """A ``reason`` column from strings, refusing values outside the kind's enum."""
    allowed = reason_values(kind)
    bad = sorted({v for v in values if v not in allowed})
    if bad:
        raise ValueError(f"reason {bad[0]!r} is not a {kind} reason ({', '.join(allowed)})")
    return pa.array(list(values), STR).dictionary_encode().cast(REASON)


def table_from_rows(rows: list[dict], schema: pa.Schema, kind: str) -> pa.Table:
    """Rows (dicts) → a table with ``schema`` (extra keys of the rows appended as float64/str columns)."""
    cols = {}
    for f in schema:
        vals = [r.get(f.name) for r in rows]
        cols[f.name] = reason_array(vals, kind) if f.name == "reason" else pa.array(vals, f.type)
    extra = [k for k in (rows[0] if rows else {}) if k not in cols]
    for k in extra:
        vals = [r.get(k) for r in rows]
        cols[k] = pa.array(vals)
    return pa.table(cols)


def check_table(table: pa.Table, kind: str, where: str = "table") -> None:
    """Raise ``ValueError`` naming the first missing or mistyped column of the kind's core schema."""
    for f in core_schema(kind):
        if f.name not in table.column_names:
            raise ValueError(f"{where}: {kind} table lacks column {f.name!r}")
        t = table.schema.field(f.name).type
        if f.name == "reason":
            if not (pa.types.is_dictionary(t) or pa.types.is_string(t)):
                raise ValueError(f"{where}: column 'reason' must be a string/dictionary column, got {t}")
        elif t != f.type and not (pa.types.is_null(t)):
            raise ValueError(f"{where}: column {f.name!r} must be {f.type}, got {t}")


def _type_fits(have: pa.DataType, want: pa.DataType) -> bool:
    """Whether a column of type ``have`` reads as ``want`` (nulls fit anything; any integer or float column a float
    one; a dictionary of strings a string one)."""
    if have == want or pa.types.is_null(have):
        return True
    if pa.types.is_dictionary(have):
        return _type_fits(have.value_type, want) or (pa.types.is_dictionary(want) and
                                                     _type_fits(have.value_type, want.value_type))
    if pa.types.is_dictionary(want):
        return pa.types.is_string(have) or pa.types.is_large_string(have)
    if pa.types.is_floating(want):
        return pa.types.is_floating(have) or pa.types.is_integer(have)
    if pa.types.is_integer(want):
        return pa.types.is_integer(have)
    if pa.types.is_string(want):
        return pa.types.is_string(have) or pa.types.is_large_string(have)
    return False


def check_schema(table: pa.Table, schema: pa.Schema, where: str, *, required: tuple | None = None) -> None:
    """Raise ``ValueError`` naming the first column of ``schema`` that ``table`` lacks (of ``required``, default all)
    or holds with a type its readers cannot use (strings where numbers belong, ...)."""
    names = set(table.column_names)
    need = schema.names if required is None else required
    for name in need:
        if name not in names:
            raise ValueError(f"{where}: lacks column {name!r}")
    for f in schema:
        if f.name in names and not _type_fits(table.schema.field(f.name).type, f.type):
            raise ValueError(f"{where}: column {f.name!r} must be {f.type}, got {table.schema.field(f.name).type}")


def kind_of_table_name(name: str) -> str | None:
    """The registered kind whose ``table_names`` hold ``name`` (``measurements`` → ``landmark``), or None."""
    from renderlab import plugins

    return next((k.name for k in plugins.observable_kinds() if name in k.table_names), None)


def expected_kind(name: str, table: pa.Table) -> str:
    """The kind a campaign table is meant to be: a name a kind claims (``table_names``: ``measurements`` is a landmark
    table) is of that kind; any other table holding more than half of a kind's core columns (beside
    ``campaign``/``run``) is of that kind (the highest share, then the most core columns, then the first registered);
    else ``"other"``."""
    named = kind_of_table_name(name)
    if named is not None:
        return named
    whole = table_kind(table)  # every core column of a kind there: that kind
    if whole != "other":
        return whole
    names = set(table.column_names)
    share = {}
    for kind, schema in _core_schemas().items():
        core = [c for c in schema.names if c not in IDENTITY_COLUMNS]
        share[kind] = (sum(c in names for c in core) / len(core), len(core)) if core else (0.0, 0)
    best = max(share, key=share.get, default=None)  # the highest share, then the most core columns, then first
    return best if best is not None and share[best][0] > 0.5 else "other"


def check_campaign_table(name: str, table: pa.Table, where: str, *, reduced: bool = False) -> str:
    """Check a campaign table against the schema of the kind it is meant to be (:func:`expected_kind`): every core
    column there (not for a ``reduced`` published table, which holds only what its report reads), every known
    column typed as the readers need. Returns the kind; ``ValueError`` otherwise."""
    kind = expected_kind(name, table)
    if kind != "other":
        required = () if reduced else tuple(core_schema(kind).names)
        check_schema(table, known_schema(kind), f"{where} ({kind} table)", required=required)
    return kind


def read_parquet(path, where: str, *, schema: pa.Schema | None = None, limit: int | None = None) -> pa.Table:
    """A Parquet file read with its boundaries checked: a regular file of at most ``limit`` bytes
    (:func:`renderlab.inputs.open_regular`), footer readable, rows and uncompressed size (as the footer
    states them) within bounds before any column is decoded, and ``schema``'s columns present and typed
    (:func:`check_schema`). Every failure is one :class:`~renderlab.errors.UserError` line naming ``where``."""
    import os

    import pyarrow.parquet as pq


    limit = LIMITS["table"] if limit is None else limit
    fd, _ = open_regular(path, "table", limit)  # a regular file of bounded size (then read by name: pyarrow's I/O)
    os.close(fd)
    try:
        pf = pq.ParquetFile(os.fspath(path))
        meta = pf.metadata
        unpacked = decoded_bytes(meta)
        if meta.num_rows > MAX_TABLE_ROWS or unpacked > limit:
            raise UserError(f"{where}: the table states {meta.num_rows} rows, {unpacked} bytes unpacked; more than "
                            f"the lab reads ({MAX_TABLE_ROWS} rows, {limit} bytes)")
        table = pf.read()
    except UserError:
        raise
    except (OSError, ValueError, TypeError, IndexError, KeyError, pa.ArrowException) as exc:
        text = " ".join(str(exc).split())[:120]
        raise UserError(f"cannot read {where}: not a readable Parquet table ({text})") from None
    if schema is not None:
        try:
            check_schema(table, schema, where)
        except ValueError as exc:
            raise UserError(str(exc)) from None
    return table


#: the most rows a table read by the lab may hold
MAX_TABLE_ROWS = 50_000_000
#: bytes per value once decoded, by Parquet physical type (BYTE_ARRAY: its offset; the data counts in the pages)
_VALUE_BYTES = {"BOOLEAN": 1, "INT32": 4, "FLOAT": 4, "INT64": 8, "DOUBLE": 8, "INT96": 12, "BYTE_ARRAY": 8}


def decoded_bytes(meta) -> int:
    """A lower bound of a Parquet file's size once decoded, from its footer alone: rows × the value width of every
    column plus the encoded pages (a column of a billion zeros run-length-encodes into a few bytes but decodes into
    8 GB)."""
    schema = meta.schema
    width = sum(_VALUE_BYTES.get(schema.column(i).physical_type, schema.column(i).length or 8)
                for i in range(meta.num_columns))
    pages = sum(meta.row_group(i).total_byte_size for i in range(meta.num_row_groups))
    return meta.num_rows * width + pages


def empty_landmark_table() -> pa.Table:
    """A zero-row table with the landmark runner's schema."""
    return LANDMARK_RUNNER.empty_table()
