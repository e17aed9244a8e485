"""Ray on loopback only, with token authentication: the settings Ray reads when it is first
imported. ``tests/conftest.py`` applies them before any test module imports Ray (torchrl
imports it too); ``tests/test_rllib.py`` passes them on to the clusters and processes it starts."""

LOOPBACK_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0", "RAY_AUTH_MODE": "token"}
