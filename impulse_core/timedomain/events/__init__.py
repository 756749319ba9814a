"""The event-driven rigid landing engine behind :func:`impulse_core.timedomain.landing.landing`
(that module's docstring describes the method; it re-exports the public names a user needs:
its ``__all__``).

The data flow, lowest module first:

* :mod:`.settings` and :mod:`.results`: what a landing is asked (settings, constants, errors)
  and what it returns (events, result);
* :mod:`.point`: the dynamics at (q, v), one CasADi call, and the joint laws as arrays;
* :mod:`.rows`, :mod:`.forces`, :mod:`.impact_law`: a contact mode's constraint rows, its
  forces and accelerations (the mode LCP's pieces), and the impact law over those rows;
* :mod:`.twins`: identical sibling subtrees (identical toes), which the run holds alike;
* the run, :class:`.run._Landing`, composed of one mixin per concern: :mod:`.tally` (what a run
  accumulates), :mod:`.dynamics` (the point and the mode's forces along a run), :mod:`.stepping`
  (the integrators between events), :mod:`.location` (when an event happens), :mod:`.impacts`
  (the impacts), :mod:`.choice` (which mode holds after an event), :mod:`.placement` (back onto
  the constraints, and the base's chart), :mod:`.paradox` (Painleve's jams and Moreau-Jean
  bridges), :mod:`.messages` (why a run failed), and :mod:`.run` (the loop from touchdown to T).
"""
