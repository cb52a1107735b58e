"""QIF 3.0 (ISO 23952, the Quality Information Framework) in and out.

- :mod:`ita.qif.results`: a run's results as one QIF results document
  (`ita results RUN --qif FILE`);
- :mod:`ita.qif.read`, :mod:`ita.qif.mapping`, :mod:`ita.qif.specs_in`: the
  characteristics of a QIF MBD or plan file as ITA's specs, and the ones ITA does not
  measure refused with their reasons (`ita spec import FILE.qif --out DIR`);
- :mod:`ita.qif.kinds`: which QIF characteristic carries each measurement kind;
- :mod:`ita.qif.tree`: the namespace, element building and numbers as QIF writes them.

lxml is needed by this package only; nothing here downloads anything.
"""
