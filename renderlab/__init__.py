"""renderlab: an optical-navigation lab."""
__version__ = "0.1.0"
