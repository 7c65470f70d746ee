"""MOS rating studies (no Qt): the SQLite study store (:mod:`.mos`), its statistics
(:mod:`.mos_stats`) and the stimulus builders and CSV export (:mod:`.stimuli`).
"""
