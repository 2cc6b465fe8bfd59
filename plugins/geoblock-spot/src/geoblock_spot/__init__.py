"""geoblock-spot: SPOT 1-5 pushbroom sensor models for geoblock."""

__version__ = "0.1.0"
