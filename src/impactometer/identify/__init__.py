"""Identification of the impacting mass M1 and velocity V0 (paper sections 4-5)."""
