MODULE WAAM
  ! waam-planner export: 690 targets, 3 weld pass(es), 2 part module(s).
  ! Targets are in wobjWaamPlate (the plate frame in the base frame "base_link").
  PERS tooldata tWaamTorch := [TRUE, [[0.000, 0.000, 350.000], [1.000000000, 0.000000000, 0.000000000, 0.000000000]], [3.000, [0, 0, 175.0], [1, 0, 0, 0], 0, 0, 0]];
  PERS wobjdata wobjWaamPlate := [FALSE, TRUE, "", [[800.000, -50.000, 350.000], [1.000000000, 0.000000000, 0.000000000, 0.000000000]], [[0, 0, 0], [1, 0, 0, 0]]];
  PERS seamdata smWaam := [0, 0.50, [1, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0], 0, 0, [1, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0], 0, 0, 0, 0, 0, [1, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0], 1.00];
  PERS welddata wdWaam1 := [6.00, 0, [1, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0], [1, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0]];
  PERS welddata wdWaam2 := [2.50, 0, [2, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0], [2, 0, 20.0, 6.00, 0, 160.0, 0, 0, 0]];
  CONST speeddata vWeld1 := [6.00, 500, 5000, 1000];
  CONST speeddata vWeld2 := [2.50, 500, 5000, 1000];
  CONST speeddata vTravel1 := [100.00, 500, 5000, 1000];

  PROC main()
    WAAM_1;
    WAAM_2;
  ENDPROC
ENDMODULE
