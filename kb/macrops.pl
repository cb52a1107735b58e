:- module(macrops,
          [ macrop/2                    % ?NameAndFormat, ?Fields
          ]).

/** <module> Hand-written MACROPs of the Operation Planner

Generalized plans in the form of the seed's Figure 4.  MACROP lookup
(prolog/macrop.pl) consults these beside the learned MACROPs of a store file;
plan generalization writes learned ones to that file, never here.

    macrop(NameAndFormat,
           [ purpose(Goals), preconditions(Facts), adders(Facts),
             unary_constraints(Goals), n_ary_constraints(Goals),
             resources(Objects), plan(Steps) ])

A step is `step(N, Action, Predecessors)`.
*/

%!  macrop(?NameAndFormat, ?Fields:list) is nondet.
%
%   A hand-written MACROP: NameAndFormat names it and lists its variables, Fields are
%   its purpose, preconditions, adders, constraints, resources and plan.

% Figure 4: the next ultrasonic measurement with the probe already in hand, the probe
% in contact at the previous point.
macrop(measured(Id1, Tool1, Arm1, Id2),
       [ purpose([ measured(Tool1, Arm1, meas(Id2)) ]),
         preconditions([ at(Arm1, in_contact_point(meas(Id1))),
                         holding(Arm1, Tool1) ]),
         adders([ at(Arm1, in_contact_point(meas(Id2))),
                  measured(Tool1, Arm1, meas(Id2)) ]),
         unary_constraints([ type(Tool1, us_tool),
                             type(Arm1, arm) ]),
         n_ary_constraints([ can_lift(Arm1, W1),
                             weight(Tool1, W2),
                             W2 =< W1 ]),
         resources([ Tool1, Arm1 ]),
         plan([ step(1, move_retract(Arm1, Id1), []),
                step(2, move(Arm1, meas(Id1), meas(Id2)), [1]),
                step(3, apply_couplant(Arm1, Id2), [2]),
                step(4, move_contact(Arm1, Id2), [3]),
                step(5, us_measure(Tool1, Arm1, Id2), [4]) ])
       ]).
