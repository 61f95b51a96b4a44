"""Plug-in registries: landmark methods, navigation filters, studies, worlds and renderer backends by name.

Each registry maps a name to a lazily imported ``"module:attr"`` target. It is filled by the lab's own modules
(the ``BUILTIN`` tables below, so ``renderlab --help`` imports nothing heavy) and by installed packages through
Python entry points, one group per registry::

    # pyproject.toml of your package
    [project.entry-points."renderlab.landmark_methods"]
    my_ncc = "mypkg.method:MyMethod"

A name given in a data file (a scenario, ``campaign.json``) resolves **only** through a registry: a data file
never names an importable module. ``module:attr`` is accepted only where the user types it on the command line
(``renderlab measure TRUTHSET --method mypkg:MyMethod``, ``renderlab campaign ... --plugin mypkg:MyMethod``),
through :meth:`Registry.get` with ``allow_reference=True`` or :meth:`Registry.add_reference`.

An unknown name is a :class:`~renderlab.errors.UserError` listing the registered names (and the closest one).
"""

from __future__ import annotations

import difflib
from importlib.metadata import entry_points
from typing import Any

from renderlab.errors import UserError

#: registry name → (entry-point group, built-in {name: "module:attr"})
BUILTIN: dict[str, tuple[str, dict[str, str]]] = {
    "landmark_methods": ("renderlab.landmark_methods", {
        "retina": "renderlab.measurement.builtin_methods:RetinaMethod",
        "retina_refined": "renderlab.measurement.builtin_methods:RetinaRefinedMethod",
        "retina_ml": "renderlab.measurement.builtin_methods:RetinaMlMethod",
        "spc": "renderlab.measurement.builtin_methods:SpcMethod",
    }),
    "filters": ("renderlab.filters", {
        "coastline_ekf": "renderlab.measurement.builtin_filters:CoastlineEKF",
        "coastline_sqrt_ekf": "renderlab.measurement.builtin_filters:CoastlineSqrtEKF",
        "descent_ekf": "renderlab.measurement.descent_filter:DescentNavFilter",
    }),
    "measurement_sources": ("renderlab.measurement_sources", {  # the descent study's non-image sources
        "geometric": "renderlab.studies.descent_navigation.sources:GeometricSource",
    }),
    "studies": ("renderlab.studies", {
        "analytic_pointing": "renderlab.studies.analytic_pointing:STUDY",
        "retina_vs_spc": "renderlab.studies.retina_vs_spc:STUDY",
        "coastline_ekf": "renderlab.studies.coastline_ekf:STUDY",
        "unknown_satellite": "renderlab.studies.unknown_satellite:STUDY",
        "descent_navigation": "renderlab.studies.descent_navigation:STUDY",
        "descent_gnc": "renderlab.studies.descent_gnc:STUDY",
        "planet_opnav": "renderlab.studies.planet_opnav:STUDY",
    }),
    "worlds": ("renderlab.worlds", {  # renderlab.contracts.world.WorldKind objects
        "analytic": "renderlab.scenario.kinds:ANALYTIC",
        "ev5": "renderlab.scenario.kinds:EV5",
        "earth": "renderlab.scenario.kinds:EARTH",
        "microsat": "renderlab.scenario.kinds:MICROSAT",
        "planet": "renderlab.scenario.kinds:PLANET",
    }),
    "scenario_sections": ("renderlab.scenario_sections", {
        "coastline": "renderlab.studies.coastline_ekf.config:CoastlineStudyConfig",
        "unknown_satellite": "renderlab.studies.unknown_satellite.config:UnknownSatelliteStudyConfig",
        "retina_vs_spc": "renderlab.studies.retina_vs_spc.config:RetinaVsSpcConfig",
        "descent_navigation": "renderlab.studies.descent_navigation.config:DescentNavigationConfig",
        "descent_gnc": "renderlab.studies.descent_gnc.config:DescentGncConfig",
        "planet_opnav": "renderlab.studies.planet_opnav.config:PlanetOpNavConfig",
    }),
    "centre_limb_methods": ("renderlab.centre_limb_methods", {  # the centre_limb kind's methods (its method_group)
        "centroid_raw": "renderlab.measurement.centre_limb_methods:RawCentroidMethod",
        "centroid_phase": "renderlab.measurement.centre_limb_methods:PhaseCentroidMethod",
        "limb_ellipse": "renderlab.measurement.centre_limb_methods:LimbEllipseMethod",
        "horizon_opnav": "renderlab.measurement.centre_limb_methods:HorizonOpNavMethod",
        "bsk_hough_circles": "renderlab.basilisk.opnav_methods:HoughCirclesMethod",  # Basilisk (the basilisk extra)
        "bsk_hough_pixel_line": "renderlab.basilisk.opnav_methods:HoughPixelLineMethod",
        "bsk_limb_horizon": "renderlab.basilisk.opnav_methods:LimbHorizonMethod",
    }),
    "renderers": ("renderlab.renderers", {
        "mitsuba": "renderlab.render.mitsuba_backend:MitsubaBackend",
        "cycles": "renderlab.render.cycles_backend:CyclesBackend",
    }),
    "guidance": ("renderlab.guidance", {  # factories (GuidanceOptions) -> renderlab.contracts.guidance.GuidanceLaw
        "zem_zev": "renderlab.measurement.builtin_guidance:ZemZevLaw",
    }),
    "result_folders": ("renderlab.result_folders", {  # renderlab.contracts.result_folder.ResultFolderKind objects
        "crosscheck": "renderlab.crosscheck.figures:RESULT_FOLDER",
        "error_budget": "renderlab.studies.retina_vs_spc.budget.report:RESULT_FOLDER",
    }),
    "observables": ("renderlab.observables", {  # renderlab.contracts.observable.ObservableKind objects
        "landmark": "renderlab.contracts.landmark:LANDMARK",
        "filter": "renderlab.contracts.navigation:FILTER",
        "pose": "renderlab.contracts.pose:POSE",
        "centre_limb": "renderlab.contracts.centre_limb:CENTRE_LIMB",
    }),
}

_LABELS = {"landmark_methods": "landmark method", "filters": "filter", "studies": "study", "worlds": "world kind",
           "renderers": "renderer", "scenario_sections": "scenario section",
           "measurement_sources": "measurement source", "guidance": "guidance law",
           "result_folders": "result-folder kind", "observables": "observable kind",
           "centre_limb_methods": "centre_limb method"}


def _load_target(target: str, what: str) -> Any:
    mod_name, sep, attr = target.partition(":")
    if not sep or not mod_name or not attr:
        raise UserError(f"{what}: {target!r} is not of the form module:attr")
    from renderlab.contracts.refs import load

    try:
        return load(target)
    except ImportError as exc:
        raise UserError(f"{what}: cannot import {mod_name} ({exc})") from None
    except AttributeError:
        raise UserError(f"{what}: {mod_name} has no attribute {attr}") from None


class Registry:
    """Names → lazily loaded objects (module docstring)."""

    def __init__(self, name: str, group: str, builtin: dict[str, str]):
        self.name, self.group, self.label = name, group, _LABELS.get(name, name)
        self._targets: dict[str, str] = dict(builtin)
        self._objects: dict[str, Any] = {}
        self._entry_points_loaded = False

    def _load_entry_points(self) -> None:
        if self._entry_points_loaded:
            return
        self._entry_points_loaded = True
        for ep in entry_points(group=self.group):
            self._targets.setdefault(ep.name, ep.value)

    def register(self, name: str, obj: Any = None, *, target: str | None = None):
        """Register ``obj`` (or a lazy ``target`` string) under ``name``; usable as a decorator."""
        if target is not None:
            self._targets[name] = target
            self._objects.pop(name, None)
            return None
        if obj is None:
            def deco(o):
                self._objects[name] = o
                return o
            return deco
        self._objects[name] = obj
        return obj

    def unregister(self, name: str) -> None:
        self._objects.pop(name, None)
        self._targets.pop(name, None)

    def names(self) -> list[str]:
        """Every registered name (built-in, registered at run time, entry points), sorted."""
        self._load_entry_points()
        return sorted(set(self._targets) | set(self._objects))

    def __contains__(self, name: str) -> bool:
        return name in self.names()

    def unknown(self, name: str, where: str = "") -> UserError:
        names = self.names()
        close = difflib.get_close_matches(str(name), names, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        return UserError(f"{where}unknown {self.label} '{name}' (registered: {', '.join(names) or 'none'}){hint}")

    def get(self, name: str, *, allow_reference: bool = False, where: str = "") -> Any:
        """The object registered as ``name``; with ``allow_reference`` also a ``module:attr`` the user typed."""
        if name in self._objects:
            return self._objects[name]
        self._load_entry_points()
        if name in self._targets:
            obj = _load_target(self._targets[name], f"{where}{self.label} '{name}'")
            self._objects[name] = obj
            return obj
        if allow_reference and ":" in str(name):
            return _load_target(str(name), f"{where}{self.label} {name!r}")
        raise self.unknown(name, where)

    def add_reference(self, reference: str, name: str | None = None) -> str:
        """Register a user-typed ``module:attr`` (command line only) under ``name`` or the object's ``name``
        attribute (else ``attr``); returns the name."""
        obj = _load_target(reference, f"{self.label} {reference!r}")
        key = name or getattr(obj, "name", None) or reference.partition(":")[2]
        if not isinstance(key, str) or not key:
            raise UserError(f"{self.label} {reference!r}: cannot tell its name; give NAME=module:attr")
        self._objects[key] = obj
        return key


REGISTRIES: dict[str, Registry] = {n: Registry(n, g, b) for n, (g, b) in BUILTIN.items()}
landmark_methods = REGISTRIES["landmark_methods"]
filters = REGISTRIES["filters"]
measurement_sources = REGISTRIES["measurement_sources"]
studies = REGISTRIES["studies"]
worlds = REGISTRIES["worlds"]
renderers = REGISTRIES["renderers"]
scenario_sections = REGISTRIES["scenario_sections"]
result_folders = REGISTRIES["result_folders"]
guidance = REGISTRIES["guidance"]
#: observable kinds (:mod:`renderlab.contracts.observable`): everything that lists kinds reads this registry
observables = REGISTRIES["observables"]

#: world kind → the study a campaign runs when ``campaign.study`` is empty
DEFAULT_STUDY: dict[str, str] = {"analytic": "analytic_pointing", "ev5": "retina_vs_spc", "earth": "coastline_ekf",
                                 "microsat": "unknown_satellite"}


def observable(name: str):
    """The observable kind registered as ``name``, checked: an
    :class:`~renderlab.contracts.observable.ObservableKind` whose ``name`` is its registry name (else one
    :class:`~renderlab.errors.UserError` line naming the kind and what was registered)."""
    from renderlab.contracts.observable import ObservableKind

    kind = observables.get(name)
    if not isinstance(kind, ObservableKind) or kind.name != name:
        what = type(kind).__name__ if not isinstance(kind, ObservableKind) else f"ObservableKind '{kind.name}'"
        raise UserError(f"observable kind '{name}': the registered object is {what}, not an ObservableKind named "
                        f"'{name}' (renderlab.contracts.observable)")
    return kind


def observable_kinds() -> list:
    """Every registered :class:`~renderlab.contracts.observable.ObservableKind` (:func:`observable`): the lab's own in
    the order of :data:`BUILTIN` (landmark, filter, pose, centre_limb), then the others by name (the order that breaks
    ties)."""
    order = list(BUILTIN["observables"][1])
    names = sorted(observables.names(), key=lambda n: (order.index(n) if n in order else len(order), n))
    return [observable(n) for n in names]


def method_registry(kind) -> Registry:
    """The registry of an observable kind's methods (a kind or its name): the one whose entry-point group is the
    kind's ``method_group`` (``landmark`` → :data:`landmark_methods`, ``filter`` → :data:`filters`), else a new
    ``<kind>_methods`` registry made on first use and kept in :data:`REGISTRIES`."""
    kind = observable(kind) if isinstance(kind, str) else kind
    for reg in REGISTRIES.values():
        if reg.group == kind.method_group:
            return reg
    reg = Registry(f"{kind.name}_methods", kind.method_group, {})
    reg.label = f"{kind.name} method"
    REGISTRIES[reg.name] = reg
    return reg


def registry(name: str) -> Registry:
    """:data:`REGISTRIES` ``[name]``; a kind's method registry ``<kind>_methods`` is made when first asked for."""
    if name not in REGISTRIES:
        for kind in observable_kinds():
            if f"{kind.name}_methods" == name:
                return method_registry(kind)
        raise KeyError(name)
    return REGISTRIES[name]


def protocol_methods(protocol) -> set[str]:
    """The methods (and properties) a ``typing.Protocol`` declares, without ``name`` and dunders."""
    return {k for k, v in vars(protocol).items() if not k.startswith("_") and (callable(v) or isinstance(v, property))}


def kind_of_method(obj):
    """The registered observable kind whose protocol ``obj`` (a class or an instance) follows: every method the
    protocol declares is there. The kind with the most such methods wins; None when no kind fits."""
    import inspect

    if inspect.isclass(obj) and (getattr(obj, "_is_protocol", False) or inspect.isabstract(obj)):
        return None
    fits = []
    for kind in observable_kinds():
        need = protocol_methods(kind.protocol)
        if need and all(getattr(obj, m, None) is not None for m in need) \
                and all(callable(getattr(obj, m)) for m in need if not isinstance(vars(kind.protocol)[m], property)):
            fits.append((len(need), kind.name, kind))
    return max(fits)[2] if fits else None


def register_cli_plugins(texts) -> tuple:
    """Register ``--plugin [NAME=]module:attr`` references typed on the command line: a
    :class:`~renderlab.contracts.study.Study` goes to :data:`studies`, a method class to the method registry of the
    observable kind whose protocol it follows (:func:`kind_of_method`). Returns ``((registry, name, reference), ...)``
    for the campaign's workers."""
    from renderlab.contracts.study import Study

    out = []
    for text in texts or ():
        name, ref = parse_plugin(text)
        obj = _load_target(ref, f"--plugin {ref!r}")
        if isinstance(obj, Study):
            registry_name = "studies"
        else:
            kind = kind_of_method(obj)
            if kind is None:
                raise UserError(f"--plugin {ref!r}: neither a Study nor a method of a registered observable kind "
                                f"({', '.join(observables.names())})")
            registry_name = method_registry(kind).name
        key = REGISTRIES[registry_name].add_reference(ref, name)
        out.append((registry_name, key, ref))
    return tuple(out)


def parse_plugin(text: str) -> tuple[str | None, str]:
    """``NAME=module:attr`` or ``module:attr`` (the ``--plugin`` option) → (name or None, reference)."""
    name, sep, ref = text.partition("=")
    if not sep:
        return None, text
    if not name.isidentifier():
        raise UserError(f"--plugin {text!r}: NAME must be an identifier")
    return name, ref
