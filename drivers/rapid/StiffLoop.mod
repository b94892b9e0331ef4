MODULE StiffLoop
    ! Joint-target loop for joint-stiffness campaigns (task T_ROB1).
    ! The host (drivers/abb_rws.py, over Robot Web Services) writes stiff_target
    ! (robot axes in degrees, as on the FlexPendant) and stiff_time (s), then sets
    ! stiff_go to TRUE. This module moves MoveAbsJ to the target in that time,
    ! with a fine point, and clears stiff_go when the robot stands at the target.
    ! The host stops the robot with a RAPID stop. Read drivers/rapid/README.md first.

    PERS bool stiff_go := FALSE;
    PERS jointtarget stiff_target := [[0,0,0,0,30,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    PERS num stiff_time := 10;

    PROC main()
        stiff_go := FALSE;
        WHILE TRUE DO
            WaitUntil stiff_go = TRUE;
            IF stiff_time < 0.5 THEN
                ! never faster than the controller's own limits allow; \T only slows
                stiff_time := 0.5;
            ENDIF
            MoveAbsJ stiff_target, v100 \T:=stiff_time, fine, tool0;
            ! a fine point: the program continues once the robot stands still
            stiff_go := FALSE;
        ENDWHILE
    ENDPROC
ENDMODULE
