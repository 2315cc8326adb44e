"""What a run made (:class:`Result`): the stage functions' outputs and measures, read by the
report (:mod:`.report`) and every door."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Union

from ...core.model.mesh import Mesh
from ...core.model.segmentation import Segmentation
from ...core.model.surfaceset import SurfaceSet
from ...core.model.volume import Volume
from .outputs import Plan
from .recipe import Recipe


@dataclass
class Result:
    """What :func:`~anatomesh.app.flow.run.run` made: the volume read, the final surfaces (one closed :class:`Mesh` per
    label or level, mm), the final :class:`SurfaceSet`, the report dict and where files went.
    The other fields are what each stage reported (see :mod:`anatomesh.app.flow.report`)."""

    volume: Union[Volume, Segmentation]
    recipe: Recipe
    surface_set: Optional[SurfaceSet] = None
    surfaces: List[Mesh] = field(default_factory=list)
    report: Dict = field(default_factory=dict)
    plan: Optional[Plan] = None
    timings: Dict[str, float] = field(default_factory=dict)
    smoothing: Optional[Dict] = None
    decimation: Optional[Dict] = None
    cleaning: List[Dict] = field(default_factory=list)
    fixes: List[Dict] = field(default_factory=list)
    lod: List[Dict] = field(default_factory=list)
    print_check: Optional[Dict] = None
    warnings: List[str] = field(default_factory=list)
    distance: Optional[Dict] = None   # distance colouring summary
    web: Optional[Dict] = None        # the web page's summary
    preprocess: Optional[Dict] = None  # steps, parameters, measured effects
    input_facts: Optional[Dict] = None  # the input's facts for the report (describe, no histogram)
    surface_sizes: Optional[List] = None  # per surface (topology, area, volume): report.surface_sizes
    pinch_points: Optional[Dict] = None  # pinch points resolved in the shells (stages.output_shells)
    render: Optional[Dict] = None  # the Blender pictures: views (filled fractions), labels, turntable

    @property
    def report_path(self):
        return self.plan.report if self.plan else None

    @property
    def files(self):
        """The whole-scene files (combined 3MF, GLB, blend, PNG) by format."""
        return self.plan.scene if self.plan else {}
