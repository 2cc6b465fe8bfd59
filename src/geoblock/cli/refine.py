"""``geoblock refine``: an image-space correction (RPCV-0, RPCV-1, order 2) fitted to GCPs.

Generic: MODEL is any registered sensor model; it is wrapped in
:class:`~geoblock.models.corrections.ImageCorrection` and fitted by
:func:`geoblock.adjust.resect`. The refined model is written as geoblock model JSON and, on
request, in other formats through :func:`geoblock.write_model` — the plugins decide whether
they can write the refined model in their format (for example an RPC00B file for a corrected
RPC) and their messages (a warning such as a fold/refit report) are printed with the result.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from geoblock.cli.options import (
    check_outputs,
    deprecated_aliases,
    model_arg,
    model_type_opt,
    open_model_arg,
    overwrite_opt,
    positive_float,
)

if TYPE_CHECKING:
    from geoblock.adjust import ControlPoints, ResectionResult
    from geoblock.models.protocol import SensorModel

__all__ = ["refine"]


def _write_spec(ctx: click.Context, param: click.Parameter, values: tuple[str, ...],
                ) -> tuple[tuple[str | None, str], ...]:
    """``FORMAT:PATH`` -> ``(format, path)``; a bare PATH infers the format from its suffix."""
    out: list[tuple[str | None, str]] = []
    for value in values:
        fmt, sep, path = value.partition(":")
        if not sep:
            fmt, path = "", value
        if (sep and not fmt.strip()) or not path.strip():
            raise click.BadParameter(
                f"expected FORMAT:PATH (for example json:out.json), got {value!r}"
            )
        out.append((fmt.strip() or None, path))
    return tuple(out)


def _read_control(path: str, sigma_px: float) -> tuple[ControlPoints, dict[str, Any]]:
    from geoblock.adjust import ControlPoints
    from geoblock.io import read_points

    columns = read_points(path, required=("lon", "lat", "h", "row", "col"))
    return ControlPoints.from_columns(columns, sigma_row=sigma_px, sigma_col=sigma_px), columns


def _split_kinds(path: str, sigma_px: float) -> tuple[ControlPoints, ControlPoints | None]:
    import numpy as np

    from geoblock.errors import ObservationError

    points, columns = _read_control(path, sigma_px)
    if "kind" not in columns:
        raise ObservationError(f"{path}: --points needs a 'kind' column (gcp or icp)")
    kind = np.char.lower(np.char.strip(np.asarray(columns["kind"], dtype=str)))
    bad = ~np.isin(kind, ("gcp", "icp"))
    if bad.any():
        listed = ", ".join(points.id[bad][:5])
        raise ObservationError(f"{path}: kind must be gcp or icp (points {listed})")
    icp = kind == "icp"
    return points.subset(~icp), (points.subset(icp) if icp.any() else None)


def _read_block_points(ground_path: str, image_path: str, image_id: str | None,
                       sigma_px: float) -> tuple[ControlPoints, ControlPoints | None, str]:
    """GCPs and ICPs of one image from a ground CSV and an image CSV (``geoblock simulate``'s
    ``points/ground.csv`` and ``points/image.csv``, a block's point files)."""
    from geoblock.errors import ObservationError
    from geoblock.io.points import read_observations

    ground, images = read_observations(ground_path, image_path, sigma_px=sigma_px)
    assert ground is not None  # a ground file was given
    present = sorted(set(images.image.tolist()))
    if not present:
        raise ObservationError(f"{image_path}: no image measurements")
    if image_id is None:
        if len(present) > 1:
            raise click.UsageError(
                f"{image_path} holds measurements of {len(present)} images "
                f"({', '.join(present)}): choose one with --image-id"
            )
        image_id = present[0]
    elif image_id not in present:
        raise click.BadParameter(
            f"{image_id!r} has no measurement in {image_path}; its images are "
            f"{', '.join(present)}", param_hint="--image-id"
        )
    try:
        gcps = images.control_points(ground, image_id, ("gcp",))
        icps = images.control_points(ground, image_id, ("icp",))
    except ObservationError as exc:
        text = str(exc).replace("image measurements", image_path, 1)
        raise ObservationError(f"{text} (ground points: {ground_path})") from None
    return gcps, (icps if len(icps.id) else None), image_id


def _check_formats(targets: list[tuple[str | None, str]]) -> None:
    """Refuse, before the fit, an output whose format its suffix does not tell (the paths
    themselves are checked by :func:`check_outputs`: distinct, writable, not inputs)."""
    from geoblock.errors import UnsupportedFormatError
    from geoblock.io.models import _FORMATS_BY_SUFFIX

    for fmt, path in targets:
        suffix = Path(path).suffix
        if fmt is None and suffix.lower() not in _FORMATS_BY_SUFFIX:
            raise UnsupportedFormatError(
                f"{path!r}: cannot infer a model format from the suffix {suffix!r}; "
                "use FORMAT:PATH (for example rpc-txt:scene_RPC.TXT)"
            )


def _write_all(refined: SensorModel, targets: list[tuple[str | None, str]],
               ) -> list[tuple[Path, str, list[str]]]:
    """Write every ``(format, path)`` of ``targets``, or none of them.

    Each output is first written in a staging folder beside its destination
    (:func:`geoblock.io.files.staged_files`); only when every writer has succeeded are the
    files moved into place (a missing format, an unwritable model or a failing writer leaves
    the destinations untouched). Returns ``(path, format label, warning messages)`` per target.
    """
    from geoblock.errors import GeoblockError
    from geoblock.io import files, write_model

    finals = [Path(path) for _, path in targets]
    done: list[tuple[Path, str, list[str]]] = []
    with files.staged_files(finals) as staged_paths:
        for (fmt, _), final, staged in zip(targets, finals, staged_paths, strict=True):
            stage = staged.parent

            def named(text: object, staged: Path = staged, stage: Path = stage,
                      final: Path = final) -> str:
                """A message about the staged file, naming the destination instead."""
                return (str(text).replace(str(staged), str(final))
                        .replace(str(stage), str(final.parent)))

            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                try:
                    write_model(refined, staged, format=fmt)
                except GeoblockError as exc:
                    try:
                        renamed = type(exc)(named(exc))
                    except Exception:  # noqa: BLE001 - an exception class with another signature
                        renamed = GeoblockError(named(exc))
                    raise renamed from exc
            done.append((final, fmt or "from suffix",
                         [" ".join(named(w.message).split()) for w in caught]))
    return done


def _stats_table(result: ResectionResult) -> list[str]:
    lines = [
        "Accuracy (metres; errors = located - surveyed, along local east E and north N):",
        f"{'set':4s} {'n':>4s} {'RMSE E':>9s} {'RMSE N':>9s} {'RMSE 2D':>9s} {'mean E':>9s}"
        f" {'mean N':>9s} {'max E':>9s} {'max N':>9s}",
    ]
    for label, res in (("GCP", result.gcp), ("ICP", result.icp)):
        if res is None:
            continue
        s = res.stats
        lines.append(
            f"{label:4s} {s.n:4d} {s.rmse_e:9.3f} {s.rmse_n:9.3f} {s.rmse_2d:9.3f} "
            f"{s.mean_e:9.3f} {s.mean_n:9.3f} {s.max_e:9.3f} {s.max_n:9.3f}"
        )
    return lines


@deprecated_aliases(model="--model-type", ground="--ground-points", image="--image-points")
@click.command(short_help="Fit an image correction (RPCV-0/RPCV-1/order 2) to GCPs.")
@model_arg
@click.option("--gcps", "gcps_path", metavar="GCPS.csv", default=None,
              help="Ground control points: id, lon, lat, h, row, col[, sigma_row, sigma_col, "
              "sigma_e, sigma_n, sigma_h].")
@click.option("--icps", "icps_path", metavar="ICPS.csv", default=None,
              help="Independent check points (same columns): accuracy only, not fitted.")
@click.option("--points", "points_path", metavar="POINTS.csv", default=None,
              help="One file with a 'kind' column (gcp or icp) instead of --gcps/--icps.")
@click.option("--ground-points", "ground_path", metavar="GROUND.csv", default=None,
              help="Block point files instead of --gcps/--points: ground points (id, lon, lat, "
              "h[, sigma_e, sigma_n, sigma_h], kind gcp or icp), with --image-points.")
@click.option("--image-points", "image_path", metavar="IMAGE.csv", default=None,
              help="Image measurements joined with --ground-points by id (id, image, row, col"
              "[, sigma | sigma_row, sigma_col][, kind]), as 'geoblock simulate' writes them.")
@click.option("--image-id", default=None, metavar="ID",
              help="The image of --image-points to refine MODEL with (needed when it holds "
              "several).")
@click.option("--order", type=click.IntRange(0, 2), default=1, show_default=True,
              help="0: shift (RPCV-0, >= 1 GCP); 1: affine (RPCV-1, >= 3 GCPs); "
              "2: quadratic (>= 6 GCPs).")
@model_type_opt
@click.option("--sigma-px", type=float, default=0.5, callback=positive_float,
              show_default=True, metavar="PX",
              help="Image measurement sigma (pixels) of points without sigma_row/sigma_col.")
@click.option("-o", "--output", metavar="OUT.json", default=None,
              help="Refined model as geoblock JSON; default MODEL's folder and stem "
              "+ '.refined.json'.")
@click.option("--write", "writes", metavar="FORMAT:PATH", multiple=True, callback=_write_spec,
              help="Also write the refined model in FORMAT (a plugin's writer, e.g. rpc-txt); "
              "repeatable.")
@overwrite_opt
def refine(model_path: str, gcps_path: str | None, icps_path: str | None,
           points_path: str | None, ground_path: str | None, image_path: str | None,
           image_id: str | None, order: int, model_name: str | None, sigma_px: float,
           output: str | None, writes: tuple[tuple[str | None, str], ...],
           overwrite: bool) -> None:
    """Refine MODEL with an image-space correction fitted to ground control points.

    MODEL (any registered sensor model) is wrapped in a polynomial correction of its image
    coordinates, in u, v = (row, col - image centre) / (half the larger image side):
    order 0 shifts (RPCV-0), order 1 is affine (RPCV-1), order 2 quadratic. The coefficients
    (pixels) are fitted to the GCPs by weighted least squares; the command prints the
    coefficients with their sigmas, the GCP residuals and the accuracy at GCPs and ICPs
    (RMSE E, N and 2D, mean and signed maximum error, metres: Aguilar et al.'s Table 3),
    then writes the refined model.

    Point files are CSV with a header (lon, lat in degrees, h in metres above the WGS84
    ellipsoid, row, col in pixels with 0 the centre of the first pixel): --gcps/--icps, one
    --points file with a kind column, or a block's two files --ground-points and
    --image-points joined by point id (those 'geoblock simulate' writes in OUTDIR/points;
    --image-id picks the image). Nothing is written unless every output (-o and each --write)
    can be written; an output that exists is refused before any work unless --overwrite.

    \b
    Examples:
      geoblock refine scene.json --gcps gcps.csv --icps icps.csv --order 1
      geoblock refine scene_RPC.TXT --points points.csv --order 0 -o scene.rpcv0.json \\
          --write rpc-txt:scene_refined_RPC.TXT
      geoblock refine sim/images/spot1a_onboard.json --ground-points sim/points/ground.csv \\
          --image-points sim/points/image.csv --image-id spot1a --order 1
    """
    from geoblock.adjust import resect
    from geoblock.models.corrections import ImageCorrection

    block = ground_path is not None or image_path is not None
    if points_path is not None and (gcps_path or icps_path):
        raise click.UsageError("give either --points or --gcps/--icps, not both")
    if block and (points_path or gcps_path or icps_path):
        raise click.UsageError("give either --ground-points/--image-points or --points or "
                               "--gcps/--icps, not several")
    if block and (ground_path is None or image_path is None):
        raise click.UsageError("--ground-points and --image-points go together (ground "
                               "points and image measurements joined by id)")
    if image_id is not None and not block:
        raise click.UsageError("--image-id selects an image of --image-points; give "
                               "--ground-points and --image-points")
    if points_path is None and gcps_path is None and not block:
        raise click.UsageError("missing --gcps GCPS.csv (or --points with a kind column, or "
                               "--ground-points with --image-points)")

    if output is None:
        src = Path(model_path)
        output = str(src.with_name(f"{src.stem}.refined.json"))
    check_outputs({"--output": output, "--write": [path for _, path in writes]},
                  {"MODEL": model_path, "--gcps": gcps_path, "--icps": icps_path,
                   "--points": points_path, "--ground-points": ground_path,
                   "--image-points": image_path}, overwrite=overwrite)
    targets: list[tuple[str | None, str]] = [("json", output), *writes]
    _check_formats(targets)
    model = open_model_arg(model_path, model_name)
    icps: ControlPoints | None
    if ground_path is not None and image_path is not None:  # the block files (checked above)
        gcps, icps, image_id = _read_block_points(ground_path, image_path, image_id, sigma_px)
        click.echo(f"image {image_id}: {len(gcps.id)} GCPs, "
                   f"{0 if icps is None else len(icps.id)} ICPs from {image_path}")
    elif points_path is not None:
        gcps, icps = _split_kinds(points_path, sigma_px)
    else:
        assert gcps_path is not None  # checked above
        gcps, _ = _read_control(gcps_path, sigma_px)
        icps = _read_control(icps_path, sigma_px)[0] if icps_path else None

    result = resect(ImageCorrection(model, order), gcps, icps)
    refined = result.model

    lines = [result.report(), "", *_stats_table(result), ""]
    click.echo("\n".join(lines))

    for written, label, messages in _write_all(refined, targets):
        click.echo(f"refined model written to {written} ({label})")
        for text in messages:
            click.echo(f"  {text}")
