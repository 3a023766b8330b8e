"""Payload and bias identification: regressor, gravity sources, fit, compensation."""
