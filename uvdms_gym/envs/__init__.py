"""Gymnasium environments of the UVDMS benchmark."""
