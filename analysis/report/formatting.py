"""The report's number formats: the functions of :mod:`analysis.text_format`, where they
are defined (neutral ground, shared with the identification's messages), re-exported here
for the report's modules and the faces."""

from analysis.text_format import (  # noqa: F401 (re-exported)
    MICRO,
    MINUS,
    PM,
    ROUND_OFF,
    clean,
    eng,
    fixed,
    interval_kNm,
    k_kNm,
    level,
    percent,
    sig,
    utc_text,
)
