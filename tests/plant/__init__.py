"""Tests of the plant models (PCA9685, MG996R) and the OpenPLC PSM driver."""
