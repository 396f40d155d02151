"""The study: the paper's experiments and what the project measures with them.

Apart from the library (model, perception, control, plant, simulation), which nothing here is
imported by: the four experiments and their claims (:mod:`.experiments`, :mod:`.claims`,
:mod:`.reproduction`, :mod:`.report`, :mod:`.findings`), the classic IBVS baseline
(:mod:`.baseline`), the robustness map (:mod:`.robustness`), the zoo of robots (:mod:`.zoo`),
the passivity and L2-gain analysis of a run (:mod:`.analysis`) and sweeps of many runs
(:mod:`.sweep`). The command line (:mod:`pbvs_pin.cli`) is their one user.
"""
