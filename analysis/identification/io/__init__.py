"""The data in and out: tests CSV/Arrow import (measurements, table_csv), results.json and
residuals.csv are in ``result``; model.toml export (model_export), the tests'
fingerprint (data_fingerprint).
"""
