"""The engine (numpy/OpenCV, no Qt): photo -> landmarks -> personalized mesh -> FAPU; FAP vector
-> deformed mesh -> warped image with layers (mouth, gaze, lids, creases). :class:`Face` ties it
together. Imports only :mod:`editor.errors`, :mod:`editor.resources`, :mod:`editor.safeio`
(and, function-locally, the Laplacian fit of :mod:`editor.synthesis.cloning` and the expression
estimate of :mod:`editor.synthesis.fap_estimate`: see pyproject's import-linter contracts).
"""
