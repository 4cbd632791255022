"""The test suites' shared libraries: paths, synthetic cuts and parts, QIF and probe-log writers, the HIL's
scenarios, the robot road's and the ADS tests' helpers, and the PLC stand-ins run as programs by the tests."""
