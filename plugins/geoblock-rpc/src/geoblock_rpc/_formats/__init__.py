"""The parsers of :mod:`geoblock_rpc.readers`, one module per format family (private)."""
