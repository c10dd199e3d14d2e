"""The parts of the ``--speed max`` search (:mod:`trajopt.fastest` runs it): what it tries
(:mod:`.settings`), the table it writes (:mod:`.table`) and its checkpoint (:mod:`.checkpoint`)."""
