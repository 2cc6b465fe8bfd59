"""The tables of Aguilar et al. (2007), as printed.

``TABLE_3`` to ``TABLE_6``: ``{(model, n_gcps): (RMSE X, RMSE Y, RMSE 2D)}`` (metres, the
paper's strings), model one of ``RPCV-0, RPCV-1, RFM-1, CCRS``; ``TABLE_7``:
``{(model, n_gcps or "Mean"): (DEM 2 x 2, DEM 5 x 5, DEM 20 x 20)}``; ``TABLE_2``: per DEM
name, ``(grid spacing, mean error, RMSEz, maximum error)``.
"""

from __future__ import annotations

__all__ = ["DEM_TABLES", "TABLE_2", "TABLE_3", "TABLE_4", "TABLE_5", "TABLE_6", "TABLE_7",
           "PAPER_MODEL"]


def _parse(text: str) -> dict[tuple[str, int | str], tuple[str, ...]]:
    """``model count v1 v2 v3`` lines into ``{(model, count): (v1, v2, v3)}``."""
    out: dict[tuple[str, int | str], tuple[str, ...]] = {}
    for line in text.strip().splitlines():
        model, count, *values = line.split()
        out[(model, int(count) if count.isdigit() else count)] = tuple(values)
    return out


#: our model name -> the paper's (our physical model stands for Toutin's CCRS model)
PAPER_MODEL = {"RPCV-0": "RPCV-0", "RPCV-1": "RPCV-1", "RFM-1": "RFM-1", "physical": "CCRS"}

#: Table 2: the three DEMs' vertical residuals at 50 DGPS points (m)
TABLE_2 = {"dem2": ("2", "0.13", "0.31", "0.65"), "dem5": ("5", "-0.53", "1.75", "4.38"),
           "dem20": ("20", "-1.71", "5.82", "-14.53")}

#: Table 3: sensor orientation, ICPs RMSE X, Y, 2D (m)
TABLE_3 = _parse("""
RPCV-0 9 0.65 1.11 1.29
RPCV-0 18 0.61 1.08 1.24
RPCV-0 27 0.58 1.09 1.23
RPCV-0 36 0.58 1.08 1.23
RPCV-0 45 0.58 1.11 1.25
RPCV-1 9 0.69 0.74 1.02
RPCV-1 18 0.57 0.71 0.92
RPCV-1 27 0.46 0.68 0.82
RPCV-1 36 0.48 0.66 0.82
RPCV-1 45 0.47 0.68 0.83
RFM-1 9 0.43 0.87 0.97
RFM-1 18 0.46 0.43 0.63
RFM-1 27 0.45 0.46 0.64
RFM-1 36 0.40 0.45 0.60
RFM-1 45 0.40 0.47 0.62
CCRS 9 0.45 0.47 0.65
CCRS 18 0.42 0.46 0.62
CCRS 27 0.41 0.50 0.65
CCRS 36 0.40 0.52 0.66
CCRS 45 0.39 0.52 0.65
""")

#: Table 4: orthoimage with the coarse DEM (20 m, RMSEz 5.82 m), ICPs RMSE X, Y, 2D (m)
TABLE_4 = _parse("""
RPCV-0 9 0.85 1.23 1.50
RPCV-0 18 0.86 1.20 1.48
RPCV-0 27 0.87 1.18 1.47
RPCV-0 36 0.88 1.21 1.49
RPCV-0 45 0.88 1.23 1.51
RPCV-1 9 0.97 1.10 1.46
RPCV-1 18 0.91 1.04 1.38
RPCV-1 27 0.92 1.04 1.39
RPCV-1 36 0.92 1.02 1.37
RPCV-1 45 0.91 1.04 1.38
RFM-1 9 1.04 1.21 1.59
RFM-1 18 0.87 0.80 1.18
RFM-1 27 0.92 0.80 1.22
RFM-1 36 0.89 0.79 1.19
RFM-1 45 0.90 0.82 1.22
CCRS 9 1.03 0.79 1.30
CCRS 18 0.9 0.89 1.26
CCRS 27 0.92 0.76 1.20
CCRS 36 0.9 0.74 1.17
CCRS 45 0.93 0.81 1.23
""")

#: Table 5: orthoimage with the medium DEM (RMSEz 1.75 m; the table's title says a 10 m grid,
#: the text and Table 2 5 m), ICPs RMSE X, Y, 2D (m)
TABLE_5 = _parse("""
RPCV-0 9 0.82 1.26 1.50
RPCV-0 18 0.81 1.22 1.46
RPCV-0 27 0.78 1.24 1.46
RPCV-0 36 0.76 1.25 1.46
RPCV-0 45 0.76 1.28 1.49
RPCV-1 9 0.82 0.77 1.13
RPCV-1 18 0.66 0.74 1.00
RPCV-1 27 0.56 0.73 0.92
RPCV-1 36 0.54 0.71 0.89
RPCV-1 45 0.55 0.72 0.91
RFM-1 9 0.50 0.89 1.02
RFM-1 18 0.48 0.55 0.74
RFM-1 27 0.48 0.59 0.76
RFM-1 36 0.51 0.58 0.77
RFM-1 45 0.51 0.58 0.77
CCRS 9 0.49 0.61 0.78
CCRS 18 0.48 0.63 0.79
CCRS 27 0.52 0.69 0.86
CCRS 36 0.52 0.68 0.86
CCRS 45 0.50 0.65 0.82
""")

#: Table 6: orthoimage with the dense DEM (2 m, RMSEz 0.31 m), ICPs RMSE X, Y, 2D (m)
TABLE_6 = _parse("""
RPCV-0 9 0.78 1.12 1.36
RPCV-0 18 0.75 1.13 1.36
RPCV-0 27 0.66 1.10 1.28
RPCV-0 36 0.69 1.08 1.28
RPCV-0 45 0.67 1.10 1.29
RPCV-1 9 0.87 0.80 1.18
RPCV-1 18 0.70 0.79 1.06
RPCV-1 27 0.55 0.74 0.92
RPCV-1 36 0.56 0.72 0.92
RPCV-1 45 0.54 0.75 0.92
RFM-1 9 0.46 0.89 1.00
RFM-1 18 0.52 0.51 0.73
RFM-1 27 0.51 0.52 0.73
RFM-1 36 0.46 0.53 0.70
RFM-1 45 0.47 0.55 0.72
CCRS 9 0.47 0.53 0.71
CCRS 18 0.47 0.60 0.76
CCRS 27 0.45 0.59 0.74
CCRS 36 0.47 0.57 0.74
CCRS 45 0.46 0.56 0.72
""")

#: Table 7: RMSE 2D related to the DEM (orthoimage minus orientation position) for the DEMs
#: of 2, 5 and 20 m (m)
TABLE_7 = _parse("""
RPCV-0 9 0.42 0.53 1.07
RPCV-0 18 0.45 0.58 1.06
RPCV-0 27 0.41 0.58 1.04
RPCV-0 36 0.43 0.59 1.05
RPCV-0 45 0.43 0.57 1.04
RPCV-0 Mean 0.43 0.57 1.05
RPCV-1 9 0.51 0.58 1.09
RPCV-1 18 0.51 0.69 1.09
RPCV-1 27 0.54 0.60 1.11
RPCV-1 36 0.51 0.56 1.11
RPCV-1 45 0.54 0.56 1.18
RPCV-1 Mean 0.52 0.60 1.12
RFM-1 9 0.49 0.57 1.16
RFM-1 18 0.48 0.56 1.09
RFM-1 27 0.56 0.56 1.06
RFM-1 36 0.49 0.57 1.07
RFM-1 45 0.48 0.58 1.08
RFM-1 Mean 0.50 0.57 1.09
CCRS 9 0.43 0.56 1.07
CCRS 18 0.49 0.56 1.13
CCRS 27 0.42 0.57 1.04
CCRS 36 0.41 0.54 1.04
CCRS 45 0.41 0.56 1.06
CCRS Mean 0.43 0.56 1.07
""")

#: the orthoimage tables per DEM name, with the table's number
DEM_TABLES = {"dem2": ("Table 6", TABLE_6), "dem5": ("Table 5", TABLE_5),
              "dem20": ("Table 4", TABLE_4)}
