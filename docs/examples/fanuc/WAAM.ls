/PROG  WAAM
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "waam-planner";
PROG_SIZE	= 0;
CREATE		= DATE 26-01-01  TIME 00:00:00;
MODIFIED	= DATE 26-01-01  TIME 00:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 6;
MEMORY_SIZE	= 0;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,*,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/APPL
  ARC Welding Equipment : 1,*,*,*,*;
/MN
   1:  ! waam-planner: 690 targets, 3 passes ;
   2:  ! Weld Schedule 1: 6.00 mm/s ;
   3:  ! 160.0 A, 20.0 V, 6.00 m/min ;
   4:  ! Weld Schedule 2: 2.50 mm/s ;
   5:  ! 160.0 A, 20.0 V, 6.00 m/min ;
   6:  CALL WAAM_1 ;
/POS
/END
