"""The ``geometry:`` keys every planar torsional-spring kind shares (hub, pads, holes, fillets,
manufacturing limits), and the :class:`geometry.sea_spring.SpringFrame` they make.

Used by the ``sea_spring`` and ``threshold_spring`` kinds; a module whose name starts with ``_``
is not a kind (see :mod:`pipeline.studies`).
"""

from __future__ import annotations

from flexopt.geometry.sea_spring import SpringFrame
from flexopt.pipeline.study import STUDY_CONFIG
from pydantic import BaseModel, Field

__all__ = ["SpringFrameBlock"]


class SpringFrameBlock(BaseModel):
    """Envelope, mounting and manufacturing limits of a planar spring (mm)."""

    model_config = STUDY_CONFIG

    envelope_diameter_mm: float = Field(72.0, gt=0, description="the spring fits this circle")
    root_fillet_mm: float = Field(
        1.5, ge=0, le=5, description="arm springs: fillet where an arm meets hub and pad"
    )
    hub_radius_mm: float = Field(9.0, gt=0, description="hub disc radius")
    bore_diameter_mm: float = Field(6.0, ge=0, description="hub bore")
    hub_holes: int = Field(4, ge=0, le=12, description="hub bolt holes")
    hub_hole_diameter_mm: float = Field(2.7, ge=0, description="hub bolt hole diameter")
    hub_hole_circle_diameter_mm: float = Field(12.0, gt=0, description="hub bolt circle")
    pad_radius_mm: float = Field(3.5, gt=0, description="outer mounting boss radius")
    pad_hole_diameter_mm: float = Field(3.2, ge=0, description="outer bolt hole diameter")
    fillet_mm: float = Field(0.3, ge=0, description="fillet radius at concave corners")
    min_slot_mm: float = Field(0.8, gt=0, description="narrowest slot (cutting)")
    min_feature_mm: float = Field(0.5, gt=0, description="thinnest member (machining)")

    def frame(self) -> SpringFrame:
        """The :class:`geometry.sea_spring.SpringFrame` of these values: the hub is turned
        through its flange footprint a millimetre inside the rim (so the rim fillets are
        elastic), the pads are held by washers of 0.8 pad radius."""
        return SpringFrame(
            envelope_diameter_mm=self.envelope_diameter_mm,
            hub_radius_mm=self.hub_radius_mm,
            bore_diameter_mm=self.bore_diameter_mm,
            hub_holes=self.hub_holes,
            hub_hole_diameter_mm=self.hub_hole_diameter_mm,
            hub_hole_circle_diameter_mm=self.hub_hole_circle_diameter_mm,
            hub_clamp_radius_mm=max(self.hub_radius_mm - 1.0, 0.5 * self.hub_radius_mm),
            pad_radius_mm=self.pad_radius_mm,
            pad_hole_diameter_mm=self.pad_hole_diameter_mm,
            pad_clamp_radius_mm=0.8 * self.pad_radius_mm,
            fillet_mm=self.fillet_mm,
            min_slot_mm=self.min_slot_mm,
            min_feature_mm=self.min_feature_mm,
        )
