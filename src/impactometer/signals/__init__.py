"""Signal primitives shared by the identification and the controller: noise estimators (:mod:`.noise`), contact
pulses (:mod:`.pulses`), the compiled impact trigger (:mod:`.trigger`), the one rule of stage B
(:mod:`.stage_b`) and the turning-point timers of the force (:mod:`.extrema`)."""
