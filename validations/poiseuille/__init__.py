"""Start-up plane Poiseuille flow (Morris et al. 1997); its series solution is in ``reference``."""
