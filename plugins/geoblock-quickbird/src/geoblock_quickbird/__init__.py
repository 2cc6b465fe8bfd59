"""geoblock-quickbird: the DigitalGlobe/Maxar rigorous physical model for geoblock."""

__version__ = "0.1.0"
