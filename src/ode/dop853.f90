!> Dormand and Prince's 8(5,3) pair with its 7th-order dense output: its
!> Butcher tableau and its arithmetic on columns (ellroll_embedded_pair).
module ellroll_dop853
  use ellroll_kinds, only: wp
  use ellroll_exact, only: is_zero
  use ellroll_embedded_pair, only: embedded_pair_t, pair_shape_t, width, max_estimates, tolerance_ratio_cap, &
      packed_stage_columns
  implicit none
  private
  integer, private :: j, s              ! of the implied loops in the constants below

  public :: dop853_t
  public :: stages, stages_dense, end_stage, first_dense_stage, c853, a853, a_value, a_column, a_row, e5, bhh, d853, &
      in_error_estimate, in_dense_output

  ! ---- Dormand-Prince 8(5,3): E. Hairer, S. P. Norsett, G. Wanner, Solving
  ! Ordinary Differential Equations I, 2nd ed., Springer 1993 (DOP853).
  integer, parameter :: stages = 12, stages_dense = 16
  !> Stage s = end_stage is f(t + h, y_new); stages dense_stages are only for dense output.
  integer, parameter :: end_stage = stages + 1
  integer, parameter :: first_dense_stage = stages + 2
  real(wp), parameter :: c853(stages_dense) = [0.0_wp, &
      0.526001519587677318785587544488e-01_wp, 0.789002279381515978178381316732e-01_wp, &
      0.118350341907227396726757197510_wp, 0.281649658092772603273242802490_wp, &
      0.333333333333333333333333333333_wp, 0.25_wp, 0.307692307692307692307692307692_wp, &
      0.651282051282051282051282051282_wp, 0.6_wp, 0.857142857142857142857142857142_wp, &
      1.0_wp, 1.0_wp, 0.1_wp, 0.2_wp, 0.777777777777777777777777777778_wp]
  real(wp), parameter :: e5(stages + 1) = [0.1312004499419488073250102996e-1_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, -0.1225156446376204440720569753e1_wp, -0.4957589496572501915214079952_wp, &
      0.1664377182454986536961530415e1_wp, -0.3503288487499736816886487290_wp, &
      0.3341791187130174790297318841_wp, 0.8192320648511571246570742613e-1_wp, &
      -0.2235530786388629525884427845e-1_wp, 0.0_wp]
  real(wp), parameter :: bhh(3) = [0.244094488188976377952755905512_wp, &
      0.733846688281611857341361741547_wp, 0.220588235294117647058823529412e-1_wp]

  !> DOP853 a(s, j): rows 2-12 the stages, 13 the weights b, 14-16 the dense-output stages.
  real(wp), parameter :: a853(16, 15) = reshape([ &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      5.26001519587677318785587544488e-2_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      1.97250569845378994544595329183e-2_wp, 5.91751709536136983633785987549e-2_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      2.95875854768068491816892993775e-2_wp, 0.0_wp, 8.87627564304205475450678981324e-2_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      2.41365134159266685502369798665e-1_wp, 0.0_wp, -8.84549479328286085344864962717e-1_wp, &
      9.24834003261792003115737966543e-1_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      3.7037037037037037037037037037e-2_wp, 0.0_wp, 0.0_wp, &
      1.70828608729473871279604482173e-1_wp, 1.25467687566822425016691814123e-1_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      3.7109375e-2_wp, 0.0_wp, 0.0_wp, &
      1.70252211019544039314978060272e-1_wp, 6.02165389804559606850219397283e-2_wp, -1.7578125e-2_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      3.70920001185047927108779319836e-2_wp, 0.0_wp, 0.0_wp, &
      1.70383925712239993810214054705e-1_wp, 1.07262030446373284651809199168e-1_wp, -1.53194377486244017527936158236e-2_wp, &
      8.27378916381402288758473766002e-3_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      6.24110958716075717114429577812e-1_wp, 0.0_wp, 0.0_wp, &
      -3.36089262944694129406857109825_wp, -8.68219346841726006818189891453e-1_wp, 2.75920996994467083049415600797e1_wp, &
      2.01540675504778934086186788979e1_wp, -4.34898841810699588477366255144e1_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      4.77662536438264365890433908527e-1_wp, 0.0_wp, 0.0_wp, &
      -2.48811461997166764192642586468_wp, -5.90290826836842996371446475743e-1_wp, 2.12300514481811942347288949897e1_wp, &
      1.52792336328824235832596922938e1_wp, -3.32882109689848629194453265587e1_wp, -2.03312017085086261358222928593e-2_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      -9.3714243008598732571704021658e-1_wp, 0.0_wp, 0.0_wp, &
      5.18637242884406370830023853209_wp, 1.09143734899672957818500254654_wp, -8.14978701074692612513997267357_wp, &
      -1.85200656599969598641566180701e1_wp, 2.27394870993505042818970056734e1_wp, 2.49360555267965238987089396762_wp, &
      -3.0467644718982195003823669022_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      2.27331014751653820792359768449_wp, 0.0_wp, 0.0_wp, &
      -1.05344954667372501984066689879e1_wp, -2.00087205822486249909675718444_wp, -1.79589318631187989172765950534e1_wp, &
      2.79488845294199600508499808837e1_wp, -2.85899827713502369474065508674_wp, -8.87285693353062954433549289258_wp, &
      1.23605671757943030647266201528e1_wp, 6.43392746015763530355970484046e-1_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      5.42937341165687622380535766363e-2_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 4.45031289275240888144113950566_wp, &
      1.89151789931450038304281599044_wp, -5.8012039600105847814672114227_wp, 3.1116436695781989440891606237e-1_wp, &
      -1.52160949662516078556178806805e-1_wp, 2.01365400804030348374776537501e-1_wp, 4.47106157277725905176885569043e-2_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      5.61675022830479523392909219681e-2_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      2.53500210216624811088794765333e-1_wp, -2.46239037470802489917441475441e-1_wp, -1.24191423263816360469010140626e-1_wp, &
      1.5329179827876569731206322685e-1_wp, 8.20105229563468988491666602057e-3_wp, 7.56789766054569976138603589584e-3_wp, &
      -8.298e-3_wp, 0.0_wp, 0.0_wp, &
      3.18346481635021405060768473261e-2_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 2.83009096723667755288322961402e-2_wp, &
      5.35419883074385676223797384372e-2_wp, -5.49237485713909884646569340306e-2_wp, 0.0_wp, &
      0.0_wp, -1.08347328697249322858509316994e-4_wp, 3.82571090835658412954920192323e-4_wp, &
      -3.40465008687404560802977114492e-4_wp, 1.41312443674632500278074618366e-1_wp, 0.0_wp, &
      -4.28896301583791923408573538692e-1_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, -4.69762141536116384314449447206_wp, &
      7.68342119606259904184240953878_wp, 4.06898981839711007970213554331_wp, 3.56727187455281109270669543021e-1_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      -1.39902416515901462129418009734e-3_wp, 2.9475147891527723389556272149_wp, -9.15095847217987001081870187138_wp], &
      [16, 15], order=[2, 1])
  !> The nonzero a(s, j), row by row (sum over them without a test per
  !> entry): a_value(m) = a853(s, a_column(m)) for m in a_row(s):a_row(s + 1) - 1.
  integer, parameter, private :: a_count = count(abs(a853) > 0)
  real(wp), parameter :: a_value(a_count) = pack(transpose(a853), abs(transpose(a853)) > 0)
  integer, parameter :: a_column(a_count) = pack(transpose(spread([(j, j = 1, 15)], 1, 16)), abs(transpose(a853)) > 0)
  integer, parameter, private :: row_of(16, 15) = spread([(s, s = 1, 16)], 2, 15)
  integer, parameter :: a_row(17) = [(1 + count(abs(a853) > 0 .and. row_of < s), s = 1, 17)]
  !> DOP853 dense-output matrix D.
  real(wp), parameter :: d853(4, 16) = reshape([ &
      -0.84289382761090128651353491142e1_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.56671495351937776962531783590_wp, &
      -0.30689499459498916912797304727e1_wp, 0.23846676565120698287728149680e1_wp, 0.21170345824450282767155149946e1_wp, &
      -0.87139158377797299206789907490_wp, 0.22404374302607882758541771650e1_wp, 0.63157877876946881815570249290_wp, &
      -0.88990336451333310820698117400e-1_wp, 0.18148505520854727256656404962e2_wp, -0.91946323924783554000451984436e1_wp, &
      -0.44360363875948939664310572000e1_wp, 0.10427508642579134603413151009e2_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.24228349177525818288430175319e3_wp, 0.16520045171727028198505394887e3_wp, -0.37454675472269020279518312152e3_wp, &
      -0.22113666853125306036270938578e2_wp, 0.77334326684722638389603898808e1_wp, -0.30674084731089398182061213626e2_wp, &
      -0.93321305264302278729567221706e1_wp, 0.15697238121770843886131091075e2_wp, -0.31139403219565177677282850411e2_wp, &
      -0.93529243588444783865713862664e1_wp, 0.35816841486394083752465898540e2_wp, 0.19985053242002433820987653617e2_wp, &
      0.0_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, -0.38703730874935176555105901742e3_wp, -0.18917813819516756882830838328e3_wp, &
      0.52780815920542364900561016686e3_wp, -0.11573902539959630126141871134e2_wp, 0.68812326946963000169666922661e1_wp, &
      -0.10006050966910838403183860980e1_wp, 0.77771377980534432092869265740_wp, -0.27782057523535084065932004339e1_wp, &
      -0.60196695231264120758267380846e2_wp, 0.84320405506677161018159903784e2_wp, 0.11992291136182789328035130030e2_wp, &
      -0.25693933462703749003312586129e2_wp, 0.0_wp, 0.0_wp, &
      0.0_wp, 0.0_wp, -0.15418974869023643374053993627e3_wp, &
      -0.23152937917604549567536039109e3_wp, 0.35763911791061412378285349910e3_wp, 0.93405324183624310003907691704e2_wp, &
      -0.37458323136451633156875139351e2_wp, 0.10409964950896230045147246184e3_wp, 0.29840293426660503123344363579e2_wp, &
      -0.43533456590011143754432175058e2_wp, 0.96324553959188282948394950600e2_wp, -0.39177261675615439165231486172e2_wp, &
      -0.14972683625798562581422125276e3_wp], &
      [4, 16], order=[2, 1])
  !> The stages with a weight in the error estimate and in the dense output:
  !> the loops over stages skip the others at compile time.
  logical, parameter :: in_error_estimate(stages + 1) = abs(e5) > 0
  logical, parameter :: in_dense_output(16) = any(abs(d853) > 0, dim=1)

  type, extends(embedded_pair_t) :: dop853_t
  contains
    procedure, nopass :: stage_columns => dop853_stage_columns
    procedure, nopass :: scaled_errors => dop853_scaled_errors
    procedure, nopass :: error_norms => dop853_error_norms
    procedure :: build_dense => dop853_build_dense
    procedure :: dense_value => dop853_dense_value
    procedure :: dense_rate => dop853_dense_rate
    procedure, nopass :: node => dop853_node
    procedure, nopass :: shape => dop853_shape
  end type dop853_t

contains

  pure type(pair_shape_t) function dop853_shape() result(shape)
    shape = pair_shape_t(end_stage=end_stage, stages_dense=stages_dense, control_order=8)
  end function dop853_shape

  pure real(wp) function dop853_node(stage)
    integer, intent(in) :: stage
    dop853_node = c853(stage)
  end function dop853_node

  pure subroutine dop853_stage_columns(stage, columns, k, y, h, point)
    integer, intent(in) :: stage, columns
    real(wp), intent(in) :: k(width, columns, *), y(width, columns), h(width)
    real(wp), intent(out) :: point(width, columns)
    call packed_stage_columns(stage, a_value, a_column, a_row, columns, k, y, h, point)
  end subroutine dop853_stage_columns

  !> Column i's error estimates of the attempt y -> y_new: Hairer's 5th-
  !> and 3rd-order ones, each component in units of atol + rtol max(|y|,
  !> |y_new|) (tolerance_ratio_cap).
  pure subroutine dop853_scaled_errors(i, columns, k, y, y_new, h, rtol, atol, errors)
    integer, intent(in) :: i, columns
    real(wp), intent(in) :: k(width, columns, *), y(width, columns), y_new(width, columns)
    real(wp), intent(in) :: h(width), rtol(width), atol(width)
    real(wp), intent(out) :: errors(width, max_estimates)
    real(wp) :: err5(width), err3(width), scale(width)
    integer :: stage
    err5 = 0
    !GCC$ unroll 16
    do stage = 1, end_stage              ! unrolled, the tests on e5 fold away
      if (in_error_estimate(stage)) err5 = err5 + e5(stage) * k(:, i, stage)
    end do
    err3 = (y_new(:, i) - y(:, i)) / h - bhh(1) * k(:, i, 1) - bhh(2) * k(:, i, 9) - bhh(3) * k(:, i, 12)
    scale = max(atol + max(abs(y(:, i)), abs(y_new(:, i))) * rtol, tiny(1.0_wp))
    errors(:, 1) = min(abs(err5), tolerance_ratio_cap * scale) / scale
    errors(:, 2) = min(abs(err3), tolerance_ratio_cap * scale) / scale
  end subroutine dop853_scaled_errors

  !> Hairer's mix of the two estimates' norms: |h| e5^2 / sqrt(n (e5^2 + e3^2 / 100)).
  pure subroutine dop853_error_norms(n, h, sums, norms)
    integer, intent(in) :: n
    real(wp), intent(in) :: h(width), sums(width, max_estimates)
    real(wp), intent(out) :: norms(width)
    integer :: l
    do l = 1, width
      if (is_zero(sums(l, 1)) .and. is_zero(sums(l, 2))) then
        norms(l) = 0
      else
        norms(l) = abs(h(l)) * sums(l, 1) / sqrt((sums(l, 1) + 0.01_wp * sums(l, 2)) * n)
      end if
    end do
  end subroutine dop853_error_norms

  !> The interpolant's coefficients, once the dense-output stages are in
  !> self%k: Hairer's form y_old + theta (r1 + theta1 (r2 + theta (r3 + ...
  !> r7))), theta1 = 1 - theta, rewritten in powers of theta, y_old + sum_i
  !> c_i theta^i, so that a value or a rate is a tree of independent
  !> products (Estrin) rather than a chain of fourteen dependent operations.
  pure subroutine dop853_build_dense(self)
    class(dop853_t), intent(inout) :: self
    real(wp) :: delta(width), rows(width, 7), stage(width)
    integer :: s, i
    delta = self%y_new - self%y_old
    rows = 0                   ! local, fixed-size: kept in registers
    rows(:, 1) = delta
    rows(:, 2) = self%h * self%k(:, 1) - delta
    rows(:, 3) = 2 * delta - self%h * (self%k(:, end_stage) + self%k(:, 1))
    do s = 1, stages_dense
      if (.not. in_dense_output(s)) cycle
      stage = self%k(:, s)
      do i = 1, 4
        rows(:, 3 + i) = rows(:, 3 + i) + (self%h * d853(i, s)) * stage
      end do
    end do
    ! theta (r1 + theta1 (r2 + theta (r3 + theta1 (r4 + ... theta r7)))) expanded
    associate (c => self%dense_coefficients)
      c(:, 0) = rows(:, 1) + rows(:, 2)
      c(:, 1) = (rows(:, 3) - rows(:, 2)) + rows(:, 4)
      c(:, 2) = (rows(:, 5) + rows(:, 6)) - (rows(:, 3) + 2 * rows(:, 4))
      c(:, 3) = (rows(:, 4) + rows(:, 7)) - (2 * rows(:, 5) + 3 * rows(:, 6))
      c(:, 4) = (rows(:, 5) + 3 * rows(:, 6)) - 3 * rows(:, 7)
      c(:, 5) = 3 * rows(:, 7) - rows(:, 6)
      c(:, 6) = -rows(:, 7)
    end associate
    self%dense_ready = .true.
  end subroutine dop853_build_dense

  !> y(t_old + theta h), theta in [0, 1], of the last attempt's interpolant.
  pure subroutine dop853_dense_value(self, theta, y)
    class(dop853_t), intent(in) :: self
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: y(width)
    real(wp) :: theta2, theta4
    theta2 = theta * theta
    theta4 = theta2 * theta2
    associate (c => self%dense_coefficients)
      y = self%y_old + theta * (((c(:, 0) + theta * c(:, 1)) + theta2 * (c(:, 2) + theta * c(:, 3))) &
                                + theta4 * ((c(:, 4) + theta * c(:, 5)) + theta2 * c(:, 6)))
    end associate
  end subroutine dop853_dense_value

  !> dy/dtheta = h dy/dt of the interpolant at t_old + theta h.
  pure subroutine dop853_dense_rate(self, theta, rate)
    class(dop853_t), intent(in) :: self
    real(wp), intent(in) :: theta
    real(wp), intent(out) :: rate(width)
    real(wp) :: theta2, theta4
    theta2 = theta * theta
    theta4 = theta2 * theta2
    associate (c => self%dense_coefficients)
      rate = ((c(:, 0) + (2 * theta) * c(:, 1)) + theta2 * (3 * c(:, 2) + (4 * theta) * c(:, 3))) &
             + theta4 * ((5 * c(:, 4) + (6 * theta) * c(:, 5)) + (7 * theta2) * c(:, 6))
    end associate
  end subroutine dop853_dense_rate
end module ellroll_dop853
