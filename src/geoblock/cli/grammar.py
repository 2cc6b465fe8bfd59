"""The command line's grammar: one spelling and one meaning per option, across every command.

:data:`OPTIONS` is the glossary: every option a ``geoblock`` command may show in its help, with
the one thing it means wherever it appears. A command that needs a concept of this list spells
it this way; a new concept gets a new entry (and a name no entry uses). :data:`RETIRED` lists
the spellings given up for one of them, kept by the commands that had them as hidden,
deprecated aliases for one release (:func:`geoblock.cli.options.deprecated_aliases`).

``tests/cli/test_cli_grammar.py`` walks every command, the plugins' included, and fails on an
option missing from the glossary, on a retired spelling shown in a help, on one name whose
values differ between commands, and on an alias that leads nowhere; the docs' "Conventions of
every command" page prints :func:`grammar_table`.
"""

from __future__ import annotations

__all__ = ["OPTIONS", "RETIRED", "grammar_table"]

#: option -> its one meaning, in every command that has it
OPTIONS: dict[str, str] = {
    # inputs: models, images, points
    "--model": "a sensor-model file (RPB, _RPC.TXT, DIMAP, .geom, model JSON...) of an image",
    "--model-type": "the registered model to read MODEL as ('geoblock plugins' lists them)",
    "--image": "a raster: the image the points or the model belong to",
    "--image-id": "an image's id: the 'image' column of the image-measurement CSV",
    "--image-points": "the image-measurement CSV (id, image, row, col; sigma, kind optional)",
    "--ground-points": "the ground-point CSV (id, lon, lat, h; sigmas, kind optional)",
    "--gcps": "a CSV of ground control points, with their image measurements",
    "--icps": "a CSV of independent check points, with their image measurements",
    "--points": "a CSV of GCPs and ICPs told apart by a kind column",
    "--crop-offset": "the scene pixel (ROW, COL) of a crop's first pixel",
    "--no-crop": "take the image's pixels as the model's, whatever their shapes",
    "--force": "accept a model whose image id differs from the raster's",
    # the DEM
    "--dem": "the DEM: a raster (GeoTIFF, SRTM .hgt, VRT, GDAL virtual path) or const:H",
    "--dem-vertical": "the vertical datum of the DEM's heights (geoid or ellipsoid)",
    "--geoid": "the geoid grid (.gtx) of geoid heights",
    "--dem-voids": "what DEM voids become: nan, filled from the posts around, or a height",
    "--fill-height": "the ellipsoidal height wherever the DEM has none (RPC_DEM_MISSING_VALUE)",
    "--dem-interpolation": "how heights are sampled between DEM posts",
    "--dem-sigma": "the accuracy of the DEM's heights, 1 sigma, metres",
    "--height": "an ellipsoidal height, metres",
    # outputs
    "--output": "where the command writes (a file, '-' for standard output, or a directory)",
    "--overwrite": "outputs that exist already may be replaced",
    "--json": "print JSON instead of text",
    "--diagnostics": "a CSV of every candidate, kept or rejected, and why",
    "--ground-output": "a CSV of the ground rows of the control points measured",
    "--reference-diagnostics": "a CSV of every reference candidate, kept or rejected, and why",
    # reference orthoimage
    "--reference": "a georeferenced orthoimage ground control is measured on",
    "--reference-accuracy": "the reference orthoimage's absolute accuracy, CE90, metres",
    "--reference-local-accuracy": "the reference orthoimage's local (point-to-point) accuracy, "
                                  "CE90, metres",
    "--reference-band": "the band of the reference orthoimage matched, 1-based",
    "--contribution": "a raster of the index of the ortho each mosaic pixel came from",
    "--write": "also write the model as FORMAT:PATH (a plugin's writer)",
    "--format": "the file format of OUT",
    "--cog": "write a Cloud-Optimized GeoTIFF",
    "--compress": "the compression of a GeoTIFF written",
    "--level": "the compression level",
    "--co": "a GDAL creation option KEY=VALUE of a GeoTIFF written",
    "--allow-empty": "write an output with no valid pixel (with a warning) instead of failing",
    "--nodata": "the nodata value of the raster written",
    "--accuracy-layer": "also write the predicted horizontal error of every pixel, metres",
    "--source-accuracy": "the accuracy layer of each input ortho, in the same order",
    "--no-accuracy-layer": "do not write the accuracy layer",
    "--no-figures": "do not draw the PNG figures",
    "--no-images": "do not render the simulated raw images",
    # grids and computation
    "--crs": "a coordinate reference system (EPSG code, WKT, PROJ string)",
    "--res": "the output pixel size, CRS units",
    "--bounds": "the output extent XMIN YMIN XMAX YMAX, CRS units",
    "--shape": "an image size ROWS COLS",
    "--resampling": "the image resampling kernel",
    "--tolerance": "the largest error of an approximation, in the units its help states",
    "--chunks": "the chunk side, pixels (does not change the result)",
    "--max-pixels": "refuse output grids of more pixels than this",
    "--scheduler": "where dask computes: threads, processes, synchronous or a scheduler address",
    "--progress": "show a progress bar",
    "--method": "the method of the command's one algorithm, among the choices it lists",
    "--intersection": "the ray/DEM intersection method",
    "--intersection-tolerance": "the ray/DEM intersection's convergence tolerance, metres",
    "--feather": "the cap of the feathering weights, pixels",
    # estimation
    "--order": "the polynomial order of the command's correction, model or bias",
    "--sigma-px": "the image measurements' standard deviation, pixels",
    "--mode": "block or single adjustment",
    "--compare-single": "also run the single adjustment, for comparison",
    "--dem-control": "the DEM elevation control of the tie points",
    "--robust": "the robust estimator of the image measurements",
    "--collocation": "least-squares collocation after the adjustment",
    "--max-iterations": "the iteration cap of an iterative solver",
    "--components": "what an adjustment does with groups of images that nothing links",
    "--solver": "how the adjustment's reduced normal equations are solved",
    "--start": "a previous adjustment's output to start from (warm start)",
    "--common-denominator": "one RFM denominator for rows and columns",
    "--regularization": "the Tikhonov weight of a fit (a number, or gcv)",
    "--grid": "the fit grid ROWS COLS HEIGHTS",
    "--max-error-px": "refuse an approximation whose largest check error exceeds this, pixels",
    # matching
    "--search": "how far the models may disagree, pixels",
    "--max-keypoints": "keypoints per image",
    "--min-overlap": "the smallest overlap of a pair of images matched, share of the smaller",
    "--max-pairs-per-image": "the pairs matched per image at most, largest overlaps first",
    "--min-convergence": "the smallest angle between two images' lines of sight, degrees",
    "--max-convergence": "the largest angle between two images' lines of sight, degrees",
    "--pairs-only": "print the pair graph and stop before matching",
    "--contrast-threshold": "SIFT's contrast threshold",
    "--ratio": "Lowe's ratio test",
    "--min-score": "the smallest correlation of a refined match",
    "-k": "the rejection threshold, robust sigmas",
    "--ictp-share": "the share of tie points written as ICTPs",
    "--id-prefix": "the prefix of the tie-point ids",
    # runs
    "--variant": "the size of a simulated run: small (seconds) or larger ones (full, tiny)",
    "--seed": "the seed of every random draw",
    "--images": "about this many images in a large simulated block",
    "--tps": "the tie points of a whole simulated block",
    "--onboard-errors": "the simulated on-board error model: realistic or bias-drift",
    "--repeats": "repetitions over seeds",
    "--list": "list the choices and exit",
}

#: retired spelling -> the one that replaces it (each command that had it keeps it as a hidden,
#: deprecated alias for one release)
RETIRED: dict[str, str] = {
    "--vertical": "--dem-vertical",
    "--out": "--output",
    "--id": "--image-id",
    "--sigma": "--sigma-px",
    "--size": "--variant",
    "--full": "--variant full",
    "--ground": "--ground-points",
    "--interpolation": "--dem-interpolation",
}


def grammar_table() -> str:
    """The glossary as a Markdown table (the docs' "Conventions of every command" page)."""
    lines = ["| option | means, in every command that has it |", "| --- | --- |"]
    lines += [f"| `{name}` | {meaning} |" for name, meaning in OPTIONS.items()]
    lines += ["", "| retired spelling | use |", "| --- | --- |"]
    lines += [f"| `{old}` | `{new}` |" for old, new in RETIRED.items()]
    return "\n".join(lines) + "\n"
