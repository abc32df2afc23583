"""The reference backend (registry name ``reference``)."""
