"""The vendor's direct model (image -> ground) of Pleiades / SPOT 6-7 DIMAP RPCs.

DIMAP v2 ``RPC_*.XML`` (and the ``DIM_*.XML`` naming it) and the Pleiades ``PHRDIMAP`` carry,
beside the inverse model (ground -> image: the RPC00B that :class:`~geoblock_rpc.RpcModel`
evaluates), a ``Direct_Model``: rational functions of the normalised image coordinates and
height giving longitude and latitude. Both are fits, made by the vendor, of the same physical
model, so they disagree slightly: the inverse model iterated to 1e-8 px (what
:meth:`RpcModel.backproject <geoblock_rpc.RpcModel.backproject_with_status>` always does, as
GDAL, rpcm and shareloc by default do) is exact for the inverse model, the direct model is
one closed-form evaluation (no iteration) exact for itself.

Evaluation (as shareloc's ``compute_rational_function_polynomial`` with its DIMAP readers):
``x = (col - SAMP_OFF) / SAMP_SCALE``, ``y = (row - LINE_OFF) / LINE_SCALE``,
``z = (h - HEIGHT_OFF) / HEIGHT_SCALE`` with the inverse model's normalisation (offsets
1-based in the file, 0-based pixel centres here, as for the inverse model); the 20 RPC00B
terms of ``(L, P, H) = (x, y, z)``; ``lon = LONG_OFF + LONG_SCALE * Nlon / Dlon`` from
``SAMP_NUM/SAMP_DEN_COEFF`` (DIMAP v2) or ``F_LON`` (PHR DIMAP, 20 numerator then 20
denominator coefficients), ``lat`` from ``LINE_NUM/LINE_DEN_COEFF`` or ``F_LAT``.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from geoblock import GroundCoords, Status
from geoblock.errors import GeoblockWarning, ModelFormatError
from geoblock.io.metadata import XmlFields, read_xml
from geoblock.io.vsi import as_path
from geoblock.models import broadcast_float64
from geoblock.typing import ArrayLike
from geoblock_rpc.rpc00b import Rpc00b, evaluate_terms

__all__ = ["DIRECT_DISAGREEMENT_PX", "DirectModelWarning", "DirectRfm", "read_direct_rfm"]

#: Beyond this distance (pixels) between the direct model's ground point projected by the
#: inverse model and the pixel it came from, :func:`read_direct_rfm` warns. The shared Pleiades
#: and SPOT 6 products agree to 0.002-0.022 px (max over their image box at three heights).
DIRECT_DISAGREEMENT_PX = 1.0


class DirectModelWarning(GeoblockWarning):
    """A file's direct model disagrees with its inverse model by more than
    :data:`DIRECT_DISAGREEMENT_PX` (the message names the file and the distance)."""


@dataclass(frozen=True, eq=False)
class DirectRfm:
    """A vendor's direct rational function model (image -> ground at a height).

    Parameters
    ----------
    rpc : Rpc00b
        The inverse model of the same file: its normalisation (offsets and scales, 0-based
        pixel centres) is the direct model's.
    lon_num, lon_den, lat_num, lat_den : ndarray, (20,)
        Coefficients in RPC00B term order of ``(L, P, H) = (x, y, z)`` (column, row, height
        normalised).
    domain_limit : float
        Points whose normalised column or row exceeds this magnitude get OUT_OF_DOMAIN and NaN
        (the inverse model's default, 1.5).
    source : str
        The file read.
    """

    rpc: Rpc00b
    lon_num: np.ndarray
    lon_den: np.ndarray
    lat_num: np.ndarray
    lat_den: np.ndarray
    domain_limit: float = 1.5
    source: str = ""

    def inverse_agreement_px(self, n: int = 9) -> float:
        """The largest distance (pixels) between a pixel and the inverse model's projection of
        the direct model's ground point for it, over an ``n`` x ``n`` grid of the model's image
        box (``OFF -/+ SCALE``) at ``HEIGHT_OFF`` and ``HEIGHT_OFF -/+ HEIGHT_SCALE``."""
        from geoblock_rpc.model import RpcModel

        q = self.rpc
        u = np.linspace(-1.0, 1.0, n)
        r, c, h = np.meshgrid(q.line_off + u * abs(q.line_scale),
                              q.samp_off + u * abs(q.samp_scale),
                              q.height_off + np.array([-1.0, 0.0, 1.0]) * abs(q.height_scale),
                              indexing="ij")
        (lon, lat, _), status = self.backproject_with_status(r, c, h)
        (row, col), status2 = RpcModel(q).project_with_status(lon, lat, h)
        ok = (status == Status.CONVERGED) & (status2 == Status.CONVERGED)
        if not ok.any():
            return math.inf
        return float(np.max(np.hypot(row - r, col - c)[ok]))

    def backproject_with_status(self, row: ArrayLike, col: ArrayLike, h: ArrayLike
                                ) -> tuple[GroundCoords, np.ndarray]:
        """Image -> ground at height ``h`` by the direct model: one closed-form evaluation.

        Parameters
        ----------
        row, col : array_like, (*S,)
            Pixels (pixel-centre convention, (0, 0) the centre of the first pixel).
        h : array_like, (*S,)
            Metres above the WGS84 ellipsoid.

        Returns
        -------
        GroundCoords, ndarray
            ``lon, lat`` (*S,) degrees in [-180, 180), ``h`` (*S,) metres, NaN where a point is
            outside the domain (OUT_OF_DOMAIN), not finite (INVALID_INPUT) or on a zero of a
            denominator (DIVERGED); and the (*S,) uint8 :class:`~geoblock.Status`.
        """
        r, c, z = broadcast_float64(row=row, col=col, h=h)
        q = self.rpc
        x = (c - q.samp_off) / q.samp_scale
        y = (r - q.line_off) / q.line_scale
        t = evaluate_terms(x, y, (z - q.height_off) / q.height_scale)
        with np.errstate(divide="ignore", invalid="ignore"):
            lon = q.long_off + q.long_scale * (t @ self.lon_num) / (t @ self.lon_den)
            lat = q.lat_off + q.lat_scale * (t @ self.lat_num) / (t @ self.lat_den)
        status = np.full(r.shape, Status.CONVERGED, dtype=np.uint8)
        status[~(np.isfinite(lon) & np.isfinite(lat))] = Status.DIVERGED
        status[(np.abs(x) > self.domain_limit) | (np.abs(y) > self.domain_limit)] = (
            Status.OUT_OF_DOMAIN)
        status[~(np.isfinite(r) & np.isfinite(c) & np.isfinite(z))] = Status.INVALID_INPUT
        bad = status != Status.CONVERGED
        lon = np.where(bad, np.nan, (lon + 180.0) % 360.0 - 180.0)
        lat = np.where(bad, np.nan, lat)
        return GroundCoords(lon, lat, np.where(bad, np.nan, z)), status

    def backproject(self, row: ArrayLike, col: ArrayLike, h: ArrayLike) -> GroundCoords:
        """:meth:`backproject_with_status` without the status."""
        return self.backproject_with_status(row, col, h)[0]


def _numbers(doc: XmlFields, node: Any, prefix: str, label: str) -> np.ndarray:
    return np.array([doc.number(f"{prefix}_{i}", node, label) for i in range(1, 21)])


def read_direct_rfm(path: str | os.PathLike[str], **options: Any) -> DirectRfm:
    """The direct model of a DIMAP v2 ``RPC_*.XML`` / ``DIM_*.XML`` or a ``PHRDIMAP_*.XML``.

    Parameters
    ----------
    path : str or path-like
        The DIMAP document (a ``DIM_*.XML`` refers to its ``RPC_*.XML``).
    **options
        :func:`~geoblock_rpc.read_rpc`'s options (``crop_offset``...): the normalisation is
        the inverse model's as read with them.

    Returns
    -------
    DirectRfm

    Raises
    ------
    ModelFormatError
        The file has no direct model (another RPC format, a Pleiades Neo v3 document, a
        DIMAP without ``Direct_Model``) or one of its coefficients is missing or not a number;
        the message names the file and the field.
    """
    from geoblock_rpc._formats.common import _field_error, _xml_error
    from geoblock_rpc.readers import read_rpc

    path = as_path(path)
    rpc, _, extra = read_rpc(path, **options)
    fmt = extra.get("format")
    if fmt not in ("dimap-v2", "dimap-phr"):
        raise ModelFormatError(
            f"{path}: a {fmt} RPC has no direct model (image -> ground); DIMAP v2 "
            "RPC_*.XML / DIM_*.XML and PHRDIMAP_*.XML carry one"
        )
    source = extra.get("rpc_file") or str(path)
    doc = read_xml(as_path(source), _xml_error, strip_namespaces=True)
    what = "PHR_Dimap_Document" if fmt == "dimap-phr" else "DIMAP"
    doc = XmlFields(doc.source, doc.root, _field_error(what))
    gl = doc.root.find(".//Global_RFM")
    direct = None if gl is None else gl.find("Direct_Model")
    if direct is None:
        raise ModelFormatError(f"{source}: {what} Global_RFM has no Direct_Model "
                               "(image -> ground)")
    label = "Global_RFM/Direct_Model/"
    if fmt == "dimap-phr":
        f_lon = doc.numbers("F_LON", direct, label, count=40)
        f_lat = doc.numbers("F_LAT", direct, label, count=40)
        lon_num, lon_den, lat_num, lat_den = f_lon[:20], f_lon[20:], f_lat[:20], f_lat[20:]
    else:
        lon_num = _numbers(doc, direct, "SAMP_NUM_COEFF", label)
        lon_den = _numbers(doc, direct, "SAMP_DEN_COEFF", label)
        lat_num = _numbers(doc, direct, "LINE_NUM_COEFF", label)
        lat_den = _numbers(doc, direct, "LINE_DEN_COEFF", label)
    if not (math.isfinite(rpc.samp_scale) and rpc.samp_scale and rpc.line_scale):
        raise ModelFormatError(f"{source}: {what} SAMP_SCALE/LINE_SCALE give no direct model")
    model = DirectRfm(rpc, lon_num, lon_den, lat_num, lat_den, source=str(source))
    gap = model.inverse_agreement_px()
    if not gap <= DIRECT_DISAGREEMENT_PX:
        warnings.warn(DirectModelWarning(
            f"{source}: its direct model (image -> ground) disagrees with its inverse model "
            f"by up to {gap:.3g} px over the image box; geoblock's backprojection uses the "
            "inverse model"), stacklevel=2)
    return model
