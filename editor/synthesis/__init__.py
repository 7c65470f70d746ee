"""Data-driven synthesis and analysis (no Qt): FAP estimation from landmarks
(:mod:`.fap_estimate`), expression cloning (:mod:`.cloning`), the bilinear model
(:mod:`.bilinear`, :mod:`.bilinear_data`, :mod:`.bilinear_eval`, :mod:`.bilinear_photo`) and the
JAFFE evaluations (:mod:`.closed_loop`, :mod:`.jaffe_stats`). Built on the engine and formats.
"""
