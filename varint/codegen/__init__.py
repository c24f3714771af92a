"""Code generation: expressions become straight-line steppers.

Between the models (which declare their potential as a SymPy expression)
and the methods (which run steppers), this layer writes a stepper's source
for one model, scheme, number of vectors and accumulator:

* :mod:`~varint.codegen.expressions` — the derivatives a step evaluates,
  and which models get a generated stepper;
* :mod:`~varint.codegen.tm` — the TM method's step body (drifts and kicks);
* :mod:`~varint.codegen.accumulators` — an accumulator's rule, written out
  in the loop or compiled into its update;
* :mod:`~varint.codegen.interval` — the emitted stepping skeleton: the loop
  over steps and the end of every step, once for one orbit and for SIMD
  lanes;
* :mod:`~varint.codegen.stepper` — the module assembled, cached on disk
  and loaded;
* :mod:`~varint.codegen.lh` — the logarithmic-Hamiltonian stepper of
  :mod:`varint.time_transform` (its step unrolled, its loop, cached the
  same way).
"""
