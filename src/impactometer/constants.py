"""Physical constants used throughout the package (SI).

One value of gravity everywhere: the standard acceleration of gravity g_n = 9.80665 m/s² (ISO 80000-3, CGPM 1901),
which is also what the unit "g" of an accelerometer means. It is the default of ``Rig.gravity``, of the
identification and of the unit conversions; a stand at another latitude sets ``gravity`` in its TOML.
"""

#: standard acceleration of gravity g_n [m/s²]; also the value of the acceleration unit "g"
STANDARD_GRAVITY = 9.80665
#: standard atmospheric pressure [Pa]
ATMOSPHERIC_PRESSURE = 101325.0
